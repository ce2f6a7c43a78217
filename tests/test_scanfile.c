/* test_scanfile.c: the scan-file reader and writer (instrument/scanfile.h) against the reference
 * scan read independently with jansson, every error case with its message, the non-finite
 * tokens, a bit-identical write/read round trip, and the optional subframe with its pixels'
 * scans and coverage (scanfile_sub.h) on a raster worked out by hand. Runs in tests/data. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <jansson.h>

#include "check.h"
#include "instrument/scanfile.h"
#include "instrument/scanfile_sub.h"

#define REF "paperlike_scan.json"

/* A valid three-point scan with the arrays' text and one more field spliced in. */
static char *scan_text(const char *x, const char *y, const char *s, const char *more)
{
    static char buf[4096];
    snprintf(buf, sizeof buf,
             "{\"pitch_um\": 6, \"spot_radius_um\": 1.34, \"bias_dn\": 100, "
             "\"gain_e_per_dn\": 3.153, \"read_noise_e\": 5.67, \"frames\": 12%s%s,\n"
             " \"x_um\": %s, \"y_um\": %s, \"signal_dn\": %s}",
             more ? ", " : "", more ? more : "", x, y, s);
    return buf;
}

/* Parses text and checks it fails with code, field and a message containing want. */
static void expect_error(const char *text, int code, const char *want_field, const char *want)
{
    scanfile_t sf;
    err_t err = {{0}};
    const char *field = "unset";
    int rc = scanfile_parse(text, strlen(text), &sf, &field, &err);
    CHECK(rc == code);
    CHECK(sf.x_um == NULL && sf.scan.n == 0);
    CHECK(strstr(err.msg, want) != NULL);
    CHECK(strchr(err.msg, '\n') == NULL);
    CHECK(want_field ? field && strcmp(field, want_field) == 0 : field == NULL);
    if (rc != code || !strstr(err.msg, want)) fprintf(stderr, "  message: %s\n", err.msg);
}

/* Replaces key's value in a copy of the reference (NULL value: deletes it); returns the text. */
static char *ref_with(const char *key, json_t *value)
{
    json_t *root = json_load_file(REF, 0, NULL);
    if (value) json_object_set_new(root, key, value);
    else json_object_del(root, key);
    char *text = json_dumps(root, JSON_REAL_PRECISION(17));
    json_decref(root);
    return text;
}

static void test_reference(void)
{
    json_t *ref = json_load_file(REF, 0, NULL);
    CHECK(ref != NULL);
    scanfile_t sf;
    err_t err;
    CHECK(scanfile_read(REF, &sf, NULL, &err) == 0);
    const fit_scan_t *s = &sf.scan;
    CHECK(s->n == 81 && s->n == json_array_size(json_object_get(ref, "x_um")));
    CHECK(s->x_um[0] == 0.6000000000000001);
    CHECK(s->signal_dn[0] == 3872.6666666666665);
    const char *names[] = {"x_um", "y_um", "signal_dn"};
    const double *arrays[] = {s->x_um, s->y_um, s->signal_dn};
    int same = 1;
    for (int a = 0; a < 3; a++)
        for (size_t k = 0; k < s->n; k++)
            same &= arrays[a][k] ==
                    json_number_value(json_array_get(json_object_get(ref, names[a]), k));
    CHECK(same);
    CHECK(s->pitch_um == json_number_value(json_object_get(ref, "pitch_um")));
    CHECK(s->spot_radius_um == 1.34 && s->bias_dn == 100.0 && s->gain_e_per_dn == 3.153);
    CHECK(s->read_noise_e == 5.67 && s->frames == 12);
    CHECK(s->full_scale_dn == FIT_FULL_SCALE_DEFAULT); /* the file does not say */
    scanfile_free(&sf);
    scanfile_free(&sf); /* a freed struct is zeroed: freeing again is harmless */
    scanfile_free(NULL);
    json_decref(ref);
}

static void test_file_errors(void)
{
    scanfile_t sf;
    err_t err;
    CHECK(scanfile_read("no_such_scan.json", &sf, NULL, &err) == -ENOENT);
    CHECK(strstr(err.msg, "no_such_scan.json") && strstr(err.msg, "No such file"));
    CHECK(scanfile_read(".", &sf, NULL, &err) == -EISDIR); /* a directory */
    char *text = ref_with("pitch_um", NULL);
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, &err) == -EINVAL);
    CHECK(strcmp(err.msg, "missing field pitch_um") == 0);
    free(text);
}

static void test_field_errors(void)
{
    const char *req[] = {"pitch_um", "spot_radius_um", "bias_dn", "gain_e_per_dn",
                         "read_noise_e", "frames", "x_um", "y_um", "signal_dn"};
    for (size_t i = 0; i < sizeof req / sizeof req[0]; i++) {
        char *text = ref_with(req[i], NULL), want[64];
        snprintf(want, sizeof want, "missing field %s", req[i]);
        expect_error(text, -EINVAL, req[i], want);
        free(text);
    }
    struct {
        const char *key;
        json_t *value;
        const char *want;
    } cases[] = {
        {"frames", json_string("12"), "frames must be a positive integer (got a string)"},
        {"frames", json_integer(0), "frames must be a positive integer (got 0)"},
        {"frames", json_real(2.5), "frames must be a positive integer (got 2.5)"},
        {"frames", json_integer(-3), "frames must be a positive integer (got -3)"},
        {"pitch_um", json_integer(0), "pitch_um must be positive (got 0)"},
        {"pitch_um", json_string("6"), "pitch_um must be a number (got a string)"},
        {"spot_radius_um", json_real(-1.34), "spot_radius_um must be positive (got -1.34)"},
        {"gain_e_per_dn", json_integer(0), "gain_e_per_dn must be positive (got 0)"},
        {"read_noise_e", json_real(-0.5), "read_noise_e must not be negative (got -0.5)"},
        {"bias_dn", json_true(), "bias_dn must be a number (got true)"},
        {"full_scale_dn", json_string("max"), "full_scale_dn must be a number (got a string)"},
        {"x_um", json_string("abc"), "x_um must be an array of numbers (got a string)"},
        {"y_um", json_object(), "y_um must be an array of numbers (got an object)"},
        {"signal_dn", json_pack("[f, s]", 1.0, "2"),
         "signal_dn must be an array of numbers (element 1 is a string)"},
        {"x_um", json_pack("[[f]]", 1.0), "x_um must be an array of numbers (element 0 is an"},
        {"signal_dn", json_pack("[f]", 1.0), "x_um has 81 values but signal_dn has 1"},
        {"y_um", json_array(), "x_um has 81 values but y_um has 0"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *text = ref_with(cases[i].key, cases[i].value);
        expect_error(text, -EINVAL, cases[i].key, cases[i].want);
        free(text);
    }
    /* read noise may be zero; full_scale_dn is read when given, null means the default */
    scanfile_t sf;
    char *text = ref_with("read_noise_e", json_integer(0));
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, NULL) == 0 && sf.scan.read_noise_e == 0);
    scanfile_free(&sf);
    free(text);
    text = ref_with("full_scale_dn", json_integer(4095));
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, NULL) == 0);
    CHECK(sf.scan.full_scale_dn == 4095);
    scanfile_free(&sf);
    free(text);
    text = ref_with("full_scale_dn", json_null());
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, NULL) == 0);
    CHECK(sf.scan.full_scale_dn == FIT_FULL_SCALE_DEFAULT);
    scanfile_free(&sf);
    free(text);
}

static void test_syntax_errors(void)
{
    expect_error("{\"pitch_um\": 6,\n \"x_um\": }", -EINVAL, NULL, "line 2, column 10");
    expect_error("{\"pitch_um\": 6,\n \"x_um\": }", -EINVAL, NULL, "invalid JSON");
    expect_error("", -EINVAL, NULL, "invalid JSON at line 1");
    expect_error("[1, 2]", -EINVAL, NULL, "must be a JSON object (got an array)");
    expect_error("{\"frames\": 1, \"frames\": 2}", -EINVAL, NULL, "duplicate");
    /* the column of an error after rewritten tokens is the column in the original text: the
     * stray x is the 22nd character */
    expect_error("{\"x_um\": [NaN, NaN, x]}", -EINVAL, NULL, "line 1, column 21");
    expect_error("{\"x_um\": [NaN, Infinity, -Infinity, x]}", -EINVAL, NULL, "column 37");
    /* only whole tokens are rewritten */
    expect_error(scan_text("[NaNx]", "[1]", "[1]", NULL), -EINVAL, NULL, "invalid JSON");
    expect_error(scan_text("[Infinity2]", "[1]", "[1]", NULL), -EINVAL, NULL, "invalid JSON");
    expect_error(scan_text("[nan]", "[1]", "[1]", NULL), -EINVAL, NULL, "invalid JSON");
    /* a non-finite constant is named as such */
    expect_error("{\"pitch_um\": NaN, \"x_um\": []}", -EINVAL, "pitch_um",
                 "pitch_um must be a finite number (got NaN)");
    expect_error("{\"pitch_um\": 6, \"spot_radius_um\": -Infinity}", -EINVAL,
                 "spot_radius_um", "spot_radius_um must be a finite number (got -Infinity)");
}

static void test_nonfinite(void)
{
    scanfile_t sf;
    err_t err;
    const char *text =
        scan_text("[0.6, 1.2, 1.8, 2.4, NaN]", "[null, 0.6, 0.6, 0.6,0.6]",
                  "[-Infinity,Infinity, \"NaN\", \"Infinity\", \"-Infinity\"]",
                  "\"description\": \"not \\\"NaN\\\" but \\\\\", \"note\": \"Infinity\"");
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, &err) == 0);
    if (sf.scan.n == 5) {
        CHECK(sf.x_um[3] == 2.4 && isnan(sf.x_um[4]) && isnan(sf.y_um[0]));
        CHECK(sf.signal_dn[0] == -INFINITY && sf.signal_dn[1] == INFINITY);
        CHECK(isnan(sf.signal_dn[2]) && sf.signal_dn[3] == INFINITY);
        CHECK(sf.signal_dn[4] == -INFINITY);
    } else {
        CHECK(sf.scan.n == 5);
        fprintf(stderr, "  message: %s\n", err.msg);
    }
    scanfile_free(&sf);
    /* the words inside strings are left alone: a string "NaN" where a number belongs is still
     * a string, so quoting a bare token inside a string would have broken this document */
    text = scan_text("[1]", "[1]", "[1]", "\"a\": \"x NaN y\", \"b\": \"\\\\\", \"c\": [\"NaN\"]");
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, &err) == 0);
    scanfile_free(&sf);
    /* empty arrays are a valid (empty) scan */
    text = scan_text("[]", "[]", "[]", NULL);
    CHECK(scanfile_parse(text, strlen(text), &sf, NULL, &err) == 0);
    CHECK(sf.scan.n == 0 && sf.scan.pitch_um == 6 && sf.scan.frames == 12);
    scanfile_free(&sf);
    /* a buffer that is not NUL-terminated: only len bytes are read */
    text = scan_text("[1]", "[2]", "[3]", NULL);
    char *copy = malloc(strlen(text));
    memcpy(copy, text, strlen(text));
    CHECK(scanfile_parse(copy, strlen(text), &sf, NULL, &err) == 0 && sf.signal_dn[0] == 3);
    scanfile_free(&sf);
    free(copy);
}

/* Writes the reference scan (with a NaN and metadata) to a temporary file and reads it back. */
static void test_round_trip(void)
{
    scanfile_t ref, back;
    err_t err;
    CHECK(scanfile_read(REF, &ref, NULL, &err) == 0);
    ref.signal_dn[5] = NAN;
    ref.scan.full_scale_dn = 4095.5;
    char dir[] = "/tmp/test_scanfile.XXXXXX", path[64];
    CHECK(mkdtemp(dir) != NULL);
    snprintf(path, sizeof path, "%s/scan.json", dir);
    json_t *meta = json_pack("{s:s, s:{s:i}}", "description", "round trip", "sim", "seed", 7);
    CHECK(scanfile_write(path, &ref.scan, meta, &err) == 0);
    CHECK(scanfile_read(path, &back, NULL, &err) == 0);
    CHECK(back.scan.n == 81);
    if (back.scan.n == 81) {
        ref.signal_dn[5] = back.signal_dn[5] = 0; /* NaN != NaN; checked below */
        CHECK(memcmp(back.x_um, ref.x_um, 81 * sizeof(double)) == 0);
        CHECK(memcmp(back.y_um, ref.y_um, 81 * sizeof(double)) == 0);
        CHECK(memcmp(back.signal_dn, ref.signal_dn, 81 * sizeof(double)) == 0);
    }
    CHECK(back.scan.pitch_um == ref.scan.pitch_um && back.scan.frames == ref.scan.frames);
    CHECK(back.scan.gain_e_per_dn == 3.153 && back.scan.read_noise_e == 5.67);
    CHECK(back.scan.full_scale_dn == 4095.5);
    json_t *doc = json_load_file(path, 0, NULL); /* strict JSON: NaN was written as null */
    CHECK(doc && json_is_null(json_array_get(json_object_get(doc, "signal_dn"), 5)));
    CHECK(doc && strcmp(json_string_value(json_object_get(doc, "description")), "round trip") == 0);
    json_decref(doc);
    scanfile_free(&back);
    /* metadata may not redefine a contract key; a failed write keeps the earlier file */
    json_t *clash = json_pack("{s:f}", "pitch_um", 1.0);
    CHECK(scanfile_write(path, &ref.scan, clash, &err) == -EINVAL);
    CHECK(strstr(err.msg, "must not redefine pitch_um") != NULL);
    CHECK(scanfile_read(path, &back, NULL, &err) == 0 && back.scan.pitch_um == 6.0);
    scanfile_free(&back);
    char tmp[80];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    CHECK(access(tmp, F_OK) != 0);
    json_decref(clash);
    json_decref(meta);
    unlink(path);
    rmdir(dir);
    /* an empty scan writes and reads */
    fit_scan_t empty = ref.scan;
    empty.n = 0;
    FILE *f = tmpfile();
    CHECK(scanfile_dump(f, &empty, NULL, &err) == 0);
    rewind(f);
    char buf[1024];
    size_t len = fread(buf, 1, sizeof buf, f);
    fclose(f);
    CHECK(scanfile_parse(buf, len, &back, NULL, &err) == 0 && back.scan.n == 0);
    scanfile_free(&back);
    scanfile_free(&ref);
}

/* The optional subframe (scanfile.h, scanfile_sub.h): a synthetic raster of 1.5 um steps over
 * x in [-6, 6], y in [-6, 12] um of the POI's frame (6 um pixels) with a 3 x 3 sub-frame whose
 * pixel i reads 1000 i + k at point k (the POI, i = 4, is signal_dn). Written, read back bit for
 * bit; pixel (+1, -1)'s scan is the positions minus (6, -6) um and its column (i = 2) of means;
 * the coverage by the rule of scan_cover.h, worked out by hand: columns -1 and 0 are covered (the
 * raster reaches both edges, 3 x 3 positions inside), column +1 is not (the raster ends at its
 * left edge, x = 0 of that pixel), and errors name the member. */
static void test_subframe(void)
{
    enum { NX = 9, NY = 13, N = NX * NY, M = 3 };
    double x[N], y[N], sig[N], dn[N * M * M];
    for (int k = 0; k < N; k++) {
        x[k] = -6 + 1.5 * (k % NX);
        y[k] = -6 + 1.5 * (k / NX);
        for (int i = 0; i < M * M; i++)
            dn[k * M * M + i] = 1000.0 * i + k;
        sig[k] = dn[k * M * M + 4];
    }
    fit_scan_t sc = {.n = N, .x_um = x, .y_um = y, .signal_dn = sig, .pitch_um = 6,
                     .spot_radius_um = 1.34, .bias_dn = 100, .gain_e_per_dn = 3.153,
                     .read_noise_e = 5.67, .frames = 12, .full_scale_dn = 16383};
    json_t *extra = json_object();
    json_object_set_new(extra, "subframe", scanfile_subframe_json(M, 1.5, dn, N));
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    err_t err;
    CHECK(scanfile_dump(f, &sc, extra, &err) == 0);
    fclose(f);
    json_decref(extra);
    scanfile_t back, px;
    CHECK(scanfile_parse(text, len, &back, NULL, &err) == 0);
    free(text);
    CHECK(back.sub_px == M && back.sub_step_um == 1.5 && back.scan.n == N);
    CHECK(back.sub_dn && memcmp(back.sub_dn, dn, sizeof dn) == 0);
    CHECK(scanfile_pixel(&back, 1, -1, &px, &err) == 0 && px.scan.n == N);
    int same = 1;
    for (int k = 0; k < N && px.scan.n == N; k++)
        same &= px.x_um[k] == x[k] - 6 && px.y_um[k] == y[k] + 6 && px.signal_dn[k] == 2000.0 + k;
    CHECK(same);
    CHECK(px.sub_px == 0 && px.scan.pitch_um == 6 && px.scan.frames == 12);
    scanfile_free(&px);
    CHECK(scanfile_pixel(&back, 2, 0, &px, &err) == -EINVAL && strstr(err.msg, "outside"));
    scan_cover_t c;
    for (int dr = -1; dr <= 1; dr++) {
        for (int dc = -1; dc <= 0; dc++) {
            scanfile_pixel_cover(&back, dc, dr, &c);
            CHECK(c.covered && c.n_inside == 9);
        }
        scanfile_pixel_cover(&back, 1, dr, &c);
        CHECK(!c.covered && strstr(c.reason, "right edge") && c.n_inside == 0);
    }
    scanfile_free(&back);
    /* a file without one has none; null is none; bad ones name the member */
    const char *ok1 = "\"subframe\": {\"sub_px\": 3, \"step_um\": 1, "
                      "\"signal_dn\": [[0, 0, 0, 0, 5, 0, 0, 0, null]]}";
    text = scan_text("[1]", "[1]", "[5]", ok1);
    CHECK(scanfile_parse(text, strlen(text), &back, NULL, &err) == 0 && back.sub_px == 3);
    CHECK(back.sub_dn && isnan(back.sub_dn[8]) && back.sub_dn[4] == 5);
    scanfile_free(&back);
    text = scan_text("[1]", "[1]", "[5]", "\"subframe\": null");
    CHECK(scanfile_parse(text, strlen(text), &back, NULL, &err) == 0 && back.sub_px == 0);
    CHECK(scanfile_pixel(&back, 0, 0, &px, &err) == -EINVAL && strstr(err.msg, "no subframe"));
    scanfile_free(&back);
    expect_error(scan_text("[1]", "[1]", "[5]", "\"subframe\": 3"), -EINVAL, "subframe",
                 "subframe must be an object (got a number)");
    expect_error(scan_text("[1]", "[1]", "[5]",
                           "\"subframe\": {\"sub_px\": 4, \"step_um\": 1, \"signal_dn\": []}"),
                 -EINVAL, "subframe.sub_px", "subframe.sub_px must be odd (got 4)");
    expect_error(scan_text("[1]", "[1]", "[5]",
                           "\"subframe\": {\"sub_px\": 3, \"step_um\": 0, \"signal_dn\": []}"),
                 -EINVAL, "subframe.step_um", "subframe.step_um must be positive");
    expect_error(scan_text("[1]", "[1]", "[5]",
                           "\"subframe\": {\"sub_px\": 3, \"step_um\": 1, "
                           "\"signal_dn\": [[5, 5]]}"),
                 -EINVAL, "subframe.signal_dn", "subframe.signal_dn[0] has 2 values, not sub_px^2 = 9");
    expect_error(scan_text("[1]", "[1]", "[5]",
                           "\"subframe\": {\"sub_px\": 3, \"step_um\": 1, "
                           "\"signal_dn\": [[0, 0, 0, 0, 6, 0, 0, 0, 0]]}"),
                 -EINVAL, "subframe.signal_dn", "is 6 but signal_dn[0] is 5");
}

int main(void)
{
    test_reference();
    test_file_errors();
    test_field_errors();
    test_syntax_errors();
    test_nonfinite();
    test_round_trip();
    test_subframe();
    CHECK_DONE();
}
