/* cam_libcamera.cpp: the "libcamera" camera backend (cam.h), the only C++ file of ipsd: a narrow
 * shim over libcamera, built as a module of its own (libipscam_libcamera.so) that cam.c loads
 * with dlopen only when the backend is listed or opened, so that ips and ipsd link neither
 * libcamera nor libstdc++. Its one exported symbol is ipsd_cam_backend_v3() (cam_impl.h); it needs
 * nothing from the program that loads it (err_set and cam_roi_check are compiled into it). Every
 * difference between libcamera releases is kept behind the <libcamera/version.h> checks in this
 * file (Debian 12 ships 0.0.3; newer releases build too).
 *
 * What it does: one raw stream (StreamRole::Raw) at the sensor's configured size, one request
 * buffer; auto-exposure off, ExposureTime and AnalogueGain set in every request; a capture queues
 * the request, waits for it, and copies the region of interest out of the mapped buffer as 16-bit
 * values (8-bit, unpacked 10/12/16-bit little-endian and MIPI CSI-2 packed 10/12-bit raw, and
 * the luminance plane of NV12/YUV420). A request whose metadata shows an exposure more than 2 %
 * off the one asked for (controls take a few frames to apply) is queued again, up to 8 times.
 * libcamera allows one CameraManager per process: all handles share one, counted. With no camera
 * present, listing gives none and opening fails with -ENODEV "no camera found by libcamera". */
#include <libcamera/libcamera.h>
#include <libcamera/version.h>

#include <sys/mman.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <vector>

#include "cam_impl.h"
#include "cam_roi.h"

#define IPSD_LIBCAMERA_AT_LEAST(ma, mi, pa)                                                        \
    (LIBCAMERA_VERSION_MAJOR > (ma) ||                                                             \
     (LIBCAMERA_VERSION_MAJOR == (ma) &&                                                           \
      (LIBCAMERA_VERSION_MINOR > (mi) ||                                                           \
       (LIBCAMERA_VERSION_MINOR == (mi) && LIBCAMERA_VERSION_PATCH >= (pa)))))

using namespace libcamera;

namespace
{

/* ControlList::get returns std::optional<T> from 0.0.1 on, a plain T (default when absent)
 * before. */
template <typename T> bool get_control(const ControlList &l, const Control<T> &c, T *out)
{
#if IPSD_LIBCAMERA_AT_LEAST(0, 0, 1)
    auto v = l.get(c);
    if (!v) return false;
    *out = *v;
    return true;
#else
    if (!l.contains(c.id())) return false;
    *out = l.get(c);
    return true;
#endif
}

/* The process's one CameraManager, shared by every handle and counted. */
std::mutex manager_mu;
std::unique_ptr<CameraManager> manager;
int manager_users;

int manager_acquire(err_t *err)
{
    std::lock_guard<std::mutex> lock(manager_mu);
    if (manager_users++ > 0) return 0;
    /* quiet by default: libcamera's logger reads this once, when it is first used */
    setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);
    manager = std::make_unique<CameraManager>();
    int rc = manager->start();
    if (rc < 0) {
        manager.reset();
        manager_users = 0;
        return err_set(err, -ENODEV,
                       "no camera found by libcamera (its camera manager did not "
                       "start: %s)",
                       std::strerror(-rc));
    }
    return 0;
}

void manager_release()
{
    std::lock_guard<std::mutex> lock(manager_mu);
    if (--manager_users == 0) {
        manager->stop();
        manager.reset();
    }
}

struct LcCam {
    std::shared_ptr<Camera> cam;
    std::unique_ptr<CameraConfiguration> config;
    std::unique_ptr<FrameBufferAllocator> alloc;
    std::unique_ptr<Request> request;
    Stream *stream = nullptr;
    bool acquired = false, started = false;
    void *map = MAP_FAILED;
    size_t map_len = 0, map_off = 0;
    double exposure_us = 10000, gain = 1;
    double timeout_s = 0; /* 0: exposure + 5 s (cam_set_timeout) */
    cam_info_t info{};
    std::mutex mu;
    std::condition_variable cv;
    bool done = false;

    void completed(Request *)
    {
        std::lock_guard<std::mutex> lock(mu);
        done = true;
        cv.notify_all();
    }
};

/* Bits per value of the formats read, 0 for others. */
int format_bits(const PixelFormat &f)
{
    if (f == formats::R8 || f == formats::SRGGB8 || f == formats::SGRBG8 || f == formats::SGBRG8 ||
        f == formats::SBGGR8 || f == formats::NV12 || f == formats::YUV420)
        return 8;
    if (f == formats::R10 || f == formats::SRGGB10 || f == formats::SGRBG10 ||
        f == formats::SGBRG10 || f == formats::SBGGR10 || f == formats::R10_CSI2P ||
        f == formats::SRGGB10_CSI2P || f == formats::SGRBG10_CSI2P || f == formats::SGBRG10_CSI2P ||
        f == formats::SBGGR10_CSI2P)
        return 10;
    if (f == formats::R12 || f == formats::SRGGB12 || f == formats::SGRBG12 ||
        f == formats::SGBRG12 || f == formats::SBGGR12 || f == formats::SRGGB12_CSI2P ||
        f == formats::SGRBG12_CSI2P || f == formats::SGBRG12_CSI2P || f == formats::SBGGR12_CSI2P)
        return 12;
    if (f == formats::SRGGB16 || f == formats::SGRBG16 || f == formats::SGBRG16 ||
        f == formats::SBGGR16)
        return 16;
    return 0;
}

bool is_csi2p(const PixelFormat &f)
{
    return f.toString().find("CSI2P") != std::string::npos;
}

/* One value at column x of a row starting at p. */
uint16_t read_value(const uint8_t *p, int x, int bits, bool packed)
{
    if (bits == 8) return p[x];
    if (!packed) return (uint16_t)(p[2 * x] | (p[2 * x + 1] << 8));
    if (bits == 10) { /* 4 values in 5 bytes: 4 high bytes, then the 4 pairs of low bits */
        const uint8_t *g = p + (x / 4) * 5;
        return (uint16_t)((g[x % 4] << 2) | ((g[4] >> (2 * (x % 4))) & 3));
    }
    const uint8_t *g = p + (x / 2) * 3; /* 12 bit: 2 values in 3 bytes */
    return (uint16_t)((g[x % 2] << 4) | ((g[2] >> (4 * (x % 2))) & 15));
}

void fill_info(LcCam *c, const StreamConfiguration &sc)
{
    cam_info_t *in = &c->info;
    std::snprintf(in->backend, sizeof in->backend, "libcamera");
    std::snprintf(in->id, sizeof in->id, "%s", c->cam->id().c_str());
    std::string model;
    const ControlList &props = c->cam->properties();
    if (get_control(props, properties::Model, &model))
        std::snprintf(in->model, sizeof in->model, "%s", model.c_str());
    in->width = (int)sc.size.width;
    in->height = (int)sc.size.height;
    Size cell;
    in->pitch_um = get_control(props, properties::UnitCellSize, &cell) && cell.width > 0
                       ? cell.width * 1e-3 /* nm */
                       : NAN;
    in->gain_e_per_dn = in->read_noise_e = in->bias_dn = NAN;
    int bits = format_bits(sc.pixelFormat);
    in->full_scale_dn = bits ? std::ldexp(1.0, bits) - 1 : NAN;
    in->exposure_min_us = in->exposure_max_us = in->gain_min = in->gain_max = NAN;
    const ControlInfoMap &ctl = c->cam->controls();
    auto e = ctl.find(controls::ExposureTime.id());
    if (e != ctl.end()) {
        in->exposure_min_us = e->second.min().get<int32_t>();
        in->exposure_max_us = e->second.max().get<int32_t>();
    }
    auto g = ctl.find(controls::AnalogueGain.id());
    if (g != ctl.end()) {
        in->gain_min = g->second.min().get<float>();
        in->gain_max = g->second.max().get<float>();
    }
}

/* Configures one raw stream, allocates and maps its buffer, makes the request, starts. */
int setup(LcCam *c, err_t *err)
{
    /* generateConfiguration takes StreamRoles (a vector) up to 0.0.x and a Span from 0.1.0 on;
     * a vector converts to both */
    std::vector<StreamRole> roles{StreamRole::Raw};
    c->config = c->cam->generateConfiguration(roles);
    if (!c->config || c->config->empty())
        return err_set(err, -ENOTSUP, "camera %s offers no raw stream", c->cam->id().c_str());
    if (c->config->validate() == CameraConfiguration::Invalid || c->cam->configure(c->config.get()))
        return err_set(err, -EIO, "camera %s: cannot configure a raw stream", c->cam->id().c_str());
    StreamConfiguration &sc = c->config->at(0);
    if (!format_bits(sc.pixelFormat))
        return err_set(err, -ENOTSUP, "camera %s: pixel format %s is not one ipsd reads",
                       c->cam->id().c_str(), sc.pixelFormat.toString().c_str());
    c->stream = sc.stream();
    c->alloc = std::make_unique<FrameBufferAllocator>(c->cam);
    if (c->alloc->allocate(c->stream) < 1)
        return err_set(err, -ENOMEM, "camera %s: cannot allocate a frame buffer",
                       c->cam->id().c_str());
    const std::unique_ptr<FrameBuffer> &buf = c->alloc->buffers(c->stream)[0];
    const FrameBuffer::Plane &pl = buf->planes()[0];
    size_t page = 4096, off = pl.offset - pl.offset % page;
    c->map_len = pl.length + (pl.offset - off);
    c->map_off = pl.offset - off;
    c->map = mmap(nullptr, c->map_len, PROT_READ, MAP_SHARED, pl.fd.get(), (off_t)off);
    if (c->map == MAP_FAILED)
        return err_set(err, -EIO, "camera %s: cannot map the frame buffer", c->cam->id().c_str());
    c->request = c->cam->createRequest();
    if (!c->request || c->request->addBuffer(c->stream, buf.get()))
        return err_set(err, -EIO, "camera %s: cannot make a request", c->cam->id().c_str());
    c->cam->requestCompleted.connect(c, &LcCam::completed);
    fill_info(c, sc);
    if (c->cam->start()) return err_set(err, -EIO, "camera %s: cannot start", c->cam->id().c_str());
    c->started = true;
    return 0;
}

void lc_close(void *impl)
{
    LcCam *c = static_cast<LcCam *>(impl);
    if (!c) return;
    if (c->started) c->cam->stop();
    if (c->cam) c->cam->requestCompleted.disconnect(c);
    c->request.reset();
    if (c->map != MAP_FAILED) munmap(c->map, c->map_len);
    c->alloc.reset();
    if (c->acquired) c->cam->release();
    c->cam.reset();
    delete c;
    manager_release();
}

int lc_info(void *impl, cam_info_t *info, err_t *)
{
    *info = static_cast<LcCam *>(impl)->info;
    return 0;
}

int lc_set_exposure(void *impl, double us, err_t *err)
{
    LcCam *c = static_cast<LcCam *>(impl);
    if (!(us > 0) || (std::isfinite(c->info.exposure_min_us) && us < c->info.exposure_min_us) ||
        (std::isfinite(c->info.exposure_max_us) && us > c->info.exposure_max_us))
        return err_set(err, -ERANGE, "exposure %g us is outside the camera's range [%g, %g] us", us,
                       c->info.exposure_min_us, c->info.exposure_max_us);
    c->exposure_us = us;
    return 0;
}

int lc_set_gain(void *impl, double gain, err_t *err)
{
    LcCam *c = static_cast<LcCam *>(impl);
    if (!(gain > 0) || (std::isfinite(c->info.gain_min) && gain < c->info.gain_min) ||
        (std::isfinite(c->info.gain_max) && gain > c->info.gain_max))
        return err_set(err, -ERANGE, "analogue gain %g is outside the camera's range [%g, %g]",
                       gain, c->info.gain_min, c->info.gain_max);
    c->gain = gain;
    return 0;
}

/* Queues the request with the exposure and gain, waits; 0 or -EIO. */
int run_request(LcCam *c, err_t *err)
{
    c->request->reuse(Request::ReuseBuffers);
    ControlList &ctl = c->request->controls();
    ctl.set(controls::AeEnable, false);
    ctl.set(controls::ExposureTime, (int32_t)std::lround(c->exposure_us));
    ctl.set(controls::AnalogueGain, (float)c->gain);
    {
        std::lock_guard<std::mutex> lock(c->mu);
        c->done = false;
    }
    if (c->cam->queueRequest(c->request.get()) < 0)
        return err_set(err, -EIO, "camera %s: cannot queue a request", c->cam->id().c_str());
    std::unique_lock<std::mutex> lock(c->mu);
    double limit_s = c->timeout_s > 0 ? c->timeout_s : c->exposure_us * 1e-6 + 5;
    auto limit = std::chrono::microseconds((long long)(limit_s * 1e6));
    if (!c->cv.wait_for(lock, limit, [c] { return c->done; }))
        return err_set(err, -ETIMEDOUT, "camera %s: no frame within %g s", c->cam->id().c_str(),
                       limit_s);
    if (c->request->status() != Request::RequestComplete)
        return err_set(err, -EIO, "camera %s: the request was cancelled", c->cam->id().c_str());
    return 0;
}

int lc_set_timeout(void *impl, double seconds, err_t *)
{
    static_cast<LcCam *>(impl)->timeout_s = seconds;
    return 0;
}

int lc_capture(void *impl, const cam_roi_t *roi, cam_frame_t *f, err_t *err)
{
    LcCam *c = static_cast<LcCam *>(impl);
    cam_roi_t r;
    int rc = cam_roi_check(roi, c->info.width, c->info.height, &r, err);
    if (rc) return rc;
    int32_t got_us = 0;
    for (int tries = 0; tries < 8; tries++) {
        if ((rc = run_request(c, err)) != 0) return rc;
        const ControlList &md = c->request->metadata();
        if (!get_control(md, controls::ExposureTime, &got_us) ||
            std::fabs(got_us - c->exposure_us) <= 0.02 * c->exposure_us + 1)
            break;
    }
    const StreamConfiguration &sc = c->config->at(0);
    int bits = format_bits(sc.pixelFormat);
    bool packed = is_csi2p(sc.pixelFormat);
    f->roi = r;
    f->dn = static_cast<uint16_t *>(std::malloc(sizeof(uint16_t) * (size_t)r.width * r.height));
    if (!f->dn) return err_set(err, -ENOMEM, "out of memory for a frame");
    const uint8_t *base = static_cast<const uint8_t *>(c->map) + c->map_off;
    for (int y = 0; y < r.height; y++)
        for (int x = 0; x < r.width; x++)
            f->dn[(size_t)y * r.width + x] =
                read_value(base + (size_t)(r.row + y) * sc.stride, r.col + x, bits, packed);
    const ControlList &md = c->request->metadata();
    float g = (float)c->gain, temp;
    int64_t ts = 0;
    f->exposure_us = get_control(md, controls::ExposureTime, &got_us) ? got_us : c->exposure_us;
    f->gain = get_control(md, controls::AnalogueGain, &g) ? g : c->gain;
    f->timestamp_ns = get_control(md, controls::SensorTimestamp, &ts) ? ts : 0;
    f->temperature_c = get_control(md, controls::SensorTemperature, &temp) ? temp : NAN;
    return 0;
}

const struct cam_ops lc_ops = {lc_close,    lc_info,    lc_set_exposure,
                               lc_set_gain, lc_capture, lc_set_timeout};

int lc_list(cam_info_t **infos, size_t *n, err_t *err)
{
    *infos = nullptr;
    *n = 0;
    if (manager_acquire(err)) return 0; /* no manager: no cameras */
    std::vector<std::shared_ptr<Camera>> cams = manager->cameras();
    int rc = 0;
    if (!cams.empty()) {
        *infos = static_cast<cam_info_t *>(std::calloc(cams.size(), sizeof(cam_info_t)));
        if (!*infos) rc = err_set(err, -ENOMEM, "out of memory for the camera list");
    }
    for (size_t i = 0; rc == 0 && i < cams.size(); i++) {
        cam_info_t *in = &(*infos)[i];
        std::snprintf(in->backend, sizeof in->backend, "libcamera");
        std::snprintf(in->id, sizeof in->id, "%s", cams[i]->id().c_str());
        std::string model;
        if (get_control(cams[i]->properties(), properties::Model, &model))
            std::snprintf(in->model, sizeof in->model, "%s", model.c_str());
        Size px;
        if (get_control(cams[i]->properties(), properties::PixelArraySize, &px))
            in->width = (int)px.width, in->height = (int)px.height;
        in->pitch_um = in->gain_e_per_dn = in->read_noise_e = in->bias_dn = NAN;
        in->full_scale_dn = in->exposure_min_us = in->exposure_max_us = NAN;
        in->gain_min = in->gain_max = NAN;
        (*n)++;
    }
    cams.clear();
    manager_release();
    return rc;
}

int lc_open(const char *id, void **out, err_t *err)
{
    *out = nullptr;
    int rc = manager_acquire(err);
    if (rc) return rc;
    LcCam *c = new (std::nothrow) LcCam;
    if (!c) {
        manager_release();
        return err_set(err, -ENOMEM, "out of memory for the camera");
    }
    std::vector<std::shared_ptr<Camera>> cams = manager->cameras();
    if (cams.empty())
        rc = err_set(err, -ENODEV, "no camera found by libcamera");
    else if (id && *id && !(c->cam = manager->get(id)))
        rc = err_set(err, -ENODEV, "no camera '%s' found by libcamera (%zu other%s present)", id,
                     cams.size(), cams.size() == 1 ? "" : "s");
    else if (!c->cam)
        c->cam = cams[0];
    if (rc == 0 && c->cam->acquire())
        rc = err_set(err, -EBUSY, "camera %s is in use by another process", c->cam->id().c_str());
    c->acquired = rc == 0;
    if (rc == 0) rc = setup(c, err);
    if (rc) {
        lc_close(c); /* releases the manager too */
        return rc;
    }
    *out = c;
    return 0;
}

const struct cam_backend lc_backend = {CAM_BACKEND_HEADER, "libcamera", lc_list, lc_open, &lc_ops};

} /* namespace */

/* The module's entry point (cam_impl.h), the one symbol it exports. */
extern "C" __attribute__((visibility("default"))) const struct cam_backend *
ipsd_cam_backend_v3(void)
{
    return &lc_backend;
}
