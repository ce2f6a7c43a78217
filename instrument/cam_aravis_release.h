/* cam_aravis_release.h (internal to instrument/, the aravis module): releasing what an opened
 * camera holds in Aravis (its ArvCamera and ArvStream) on a thread of its own, so that closing a
 * camera that stopped answering does not wait out Aravis's commands to it; and the old stream of
 * a reset after a faulty frame, with its AcquisitionStop, for the same reason.
 *
 * Why: Aravis 0.8's finalizers talk to the camera and cannot be told not to. Unreferencing a GigE
 * Vision stream writes its channel's port register to 0; unreferencing the device joins its
 * heartbeat thread (which may be inside a register read) and then gives up the control privilege
 * (a register write). Each of these waits out 5 attempts of 500 ms (ARV_GV_DEVICE_GVCP_N_RETRIES
 * and _TIMEOUT_MS: compile-time defaults, no setter in 0.8's API), and the heartbeat holds the
 * device's command lock while it does: 4 x 2.5 s = 10 s against a vanished camera.
 *
 * A release runs on a joinable thread named "ipsd-arv-close" and ends by itself within that
 * bound. It is waited for before the same camera is opened again (its late commands must not
 * reach a camera a new handle controls) and when the module is unloaded or the program ends, so
 * no thread and nothing of Aravis's outlives the program's own end. Thread-safe. */
#ifndef IPSD_INSTRUMENT_CAM_ARAVIS_RELEASE_H
#define IPSD_INSTRUMENT_CAM_ARAVIS_RELEASE_H

#include <arv.h>

/* Releases cam and stream (either may be NULL; both references are taken over), sending
 * AcquisitionStop first when stop is set (cam must then be given). The caller waits for it at
 * most wait_s seconds (0: not at all); a release that takes longer goes on in the background.
 * gate_fd >= 0 (a test hook): the release first reads one byte from it, so that a test holds it
 * until it writes one. id names the camera (cam_info_t's id) for cam_aravis_release_wait.
 * Returns 1 when the release ended within the wait, 0 when it goes on. */
int cam_aravis_release(const char *id, ArvCamera *cam, ArvStream *stream, int stop, double wait_s,
                       int gate_fd);

/* Waits until no release of camera id (NULL: of any camera) is running, and joins the threads of
 * those that ended. */
void cam_aravis_release_wait(const char *id);

#endif
