/* test_scene.c: the simulated bench's scenes (instrument/scene.h): sensor checks, the built-in
 * maps, map files, and the exact sub-pixel truth against hand-computed overlaps and an
 * independent quadrature of the paperlike function. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>


#include "check.h"
#include "instrument/scene.h"

static const char *write_tmp(const char *name, const char *text)
{
    static char path[256];
    snprintf(path, sizeof path, "/tmp/ipsd_test_scene_%d_%s", (int)getpid(), name);
    FILE *f = fopen(path, "w");
    fputs(text, f);
    fclose(f);
    return path;
}

static void test_sensor(void)
{
    scene_sensor_t s = scene_sensor_default();
    CHECK(scene_sensor_check(&s, NULL) == 0);
    /* the paper's sensor constants (section III.A) */
    CHECK_NEAR(s.pitch_um, 6.0, 0, 0);
    CHECK_NEAR(s.gain_e_per_dn, 3.153, 0, 0);
    CHECK_NEAR(s.read_noise_e, 5.67, 0, 0);
    CHECK_NEAR(s.full_scale_dn, 16383, 0, 0);
    err_t err;
    scene_sensor_t b = s;
    b.pitch_um = -1;
    CHECK(scene_sensor_check(&b, &err) == -EINVAL && strstr(err.msg, "pitch"));
    b = s;
    b.bias_dn = 20000;
    CHECK(scene_sensor_check(&b, &err) == -EINVAL && strstr(err.msg, "bias"));
    scene_t *sc = NULL;
    CHECK(scene_open("bogus", &s, &sc, &err) == -EINVAL && strstr(err.msg, "bogus") && !sc);
    CHECK(scene_open("paperlike:0", &s, &sc, &err) == -EINVAL);
}

static void test_uniform(void)
{
    scene_sensor_t s = scene_sensor_default();
    scene_t *sc;
    CHECK(scene_open("uniform", &s, &sc, NULL) == 0);
    int m;
    const double *map = scene_map(sc, &m);
    CHECK(m == 1 && map[0] == 1.0);
    double S[100];
    for (int r = 1; r <= 10; r++) {
        CHECK(scene_truth(sc, r, S, NULL) == 0);
        for (int c = 0; c < r * r; c++)
            CHECK_NEAR(S[c], 1.0, 1e-14, 0);
    }
    CHECK(scene_stats(sc)->l1_dev == 0 && scene_stats(sc)->max == 1);
    scene_close(sc);
}

/* An independent cell mean of the paperlike function: 400 x 400 midpoint rule (error ~1e-7). */
static double midpoint_mean(double x0, double y0, double h, double p)
{
    int n = 400;
    double acc = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            acc += scene_paperlike_value(x0 + (i + 0.5) * h / n, y0 + (j + 0.5) * h / n, p);
    return acc / ((double)n * n);
}

static void test_paperlike(void)
{
    scene_sensor_t s = scene_sensor_default();
    scene_t *sc;
    CHECK(scene_open("paperlike", &s, &sc, NULL) == 0);
    int m;
    const double *map = scene_map(sc, &m);
    CHECK(m == SCENE_PAPERLIKE_RES);
    double h = s.pitch_um / m;
    int cells[][2] = {{0, 0}, {0, 15}, {29, 29}, {12, 7}, {29, 0}};
    for (size_t k = 0; k < sizeof cells / sizeof cells[0]; k++) {
        int i = cells[k][0], j = cells[k][1];
        CHECK_NEAR(map[j * m + i], midpoint_mean(i * h, j * h, h, s.pitch_um), 1e-6, 0);
    }
    /* truth: r = m is the map itself, r = 1 its mean; every r keeps the mean (a partition) */
    double S[900], mean = scene_stats(sc)->mean;
    CHECK(scene_truth(sc, m, S, NULL) == 0);
    for (int c = 0; c < m * m; c++)
        CHECK_NEAR(S[c], map[c], 1e-13, 0);
    for (int r = 1; r <= 10; r++) {
        CHECK(scene_truth(sc, r, S, NULL) == 0);
        double acc = 0;
        for (int c = 0; c < r * r; c++)
            acc += S[c] / (r * r);
        CHECK_NEAR(acc, mean, 1e-13, 0);
    }
    /* the paper's pixel at r = 7: dips of 25-30 % at the top, left and bottom edges (the
     * sub-pixel means are diluted by the sub-pixel width), none on the right */
    CHECK(scene_truth(sc, 7, S, NULL) == 0);
    double top = 0, left = 0, bottom = 0, right = 0, mid = 0;
    for (int k = 1; k < 6; k++) {
        top += S[0 * 7 + k] / 5, bottom += S[6 * 7 + k] / 5;
        left += S[k * 7 + 0] / 5, right += S[k * 7 + 6] / 5;
        for (int q = 1; q < 6; q++)
            mid += S[k * 7 + q] / 25;
    }
    CHECK(top < 0.9 * mid && left < 0.9 * mid && bottom < 0.9 * mid);
    CHECK(right > 0.97 * mid);
    /* the continuous function: 25-30 % down at the middle of the three edges, flat at the right */
    double p = s.pitch_um, c0 = scene_paperlike_value(p / 2, p / 2, p);
    CHECK(scene_paperlike_value(p / 2, 0, p) / c0 > 0.68 &&
          scene_paperlike_value(p / 2, 0, p) / c0 < 0.78);
    CHECK(scene_paperlike_value(0, p / 2, p) / c0 > 0.68 &&
          scene_paperlike_value(0, p / 2, p) / c0 < 0.78);
    CHECK(scene_paperlike_value(p, p / 2, p) / c0 > 0.9);
    scene_close(sc);
}

static void test_map_files(void)
{
    scene_sensor_t s = scene_sensor_default();
    scene_t *sc;
    err_t err;
    char spec[300];
    /* a 2 x 2 map [[a, b], [c, d]]: at r = 3 the middle sub-pixels straddle the halves */
    snprintf(spec, sizeof spec, "map:%s", write_tmp("a.json", "{\"r\": 2, \"S\": [1, 2, 3, 5]}"));
    CHECK(scene_open(spec, &s, &sc, &err) == 0);
    double S[16];
    CHECK(scene_truth(sc, 3, S, NULL) == 0);
    double want[9] = {1, 1.5, 2, 2, 2.75, 3.5, 3, 4, 5};
    for (int c = 0; c < 9; c++)
        CHECK_NEAR(S[c], want[c], 1e-14, 0);
    CHECK(scene_truth(sc, 4, S, NULL) == 0);
    CHECK(S[0] == 1 && S[1] == 1 && S[2] == 2 && S[15] == 5 && S[10] == 5 && S[8] == 3);
    scene_close(sc);
    snprintf(spec, sizeof spec, "map:%s", write_tmp("b.json", "[0.5, 1, 1, 1, 1, 1, 1, 1, 1]"));
    CHECK(scene_open(spec, &s, &sc, &err) == 0);
    int m;
    scene_map(sc, &m);
    CHECK(m == 3 && scene_stats(sc)->max == 1);
    scene_close(sc);
    /* bad files name the problem */
    const char *bad[][2] = {{"c.json", "[1, 2, 3]"},
                            {"d.json", "{\"S\": [1, -1, 1, 1]}"},
                            {"e.json", "{\"r\": 3, \"S\": [1, 1, 1, 1]}"},
                            {"f.json", "{\"S\": [1, \"x\", 1, 1]}"},
                            {"g.json", "{\"S\": [0, 0, 0, 0]}"},
                            {"h.json", "{\"S\": [1, 1, 1"}};
    const char *words[] = {"m*m", ">= 0", "\"r\"", "not a number", "zero", "line"};
    for (int k = 0; k < 6; k++) {
        snprintf(spec, sizeof spec, "map:%s", write_tmp(bad[k][0], bad[k][1]));
        sc = NULL;
        CHECK(scene_open(spec, &s, &sc, &err) == -EINVAL && sc == NULL);
        CHECK(strstr(err.msg, words[k]) != NULL);
        remove(spec + 4);
    }
    CHECK(scene_open("map:/nonexistent/ipsd/map.json", &s, &sc, &err) == -ENOENT);
    CHECK(strstr(err.msg, "/nonexistent/ipsd/map.json") != NULL);
    remove(write_tmp("a.json", ""));
    remove(write_tmp("b.json", ""));
}

int main(void)
{
    test_sensor();
    test_uniform();
    test_paperlike();
    test_map_files();
    CHECK_DONE();
}
