/* check.h: the tiny assertion macros every test executable uses. A failed CHECK prints where
 * and what, counts, and the test exits non-zero at CHECK_DONE(). Values compared come from
 * independent references (tests/data/, analytic limits), never from the code under test. */
#ifndef IPSD_TEST_CHECK_H
#define IPSD_TEST_CHECK_H

#include <math.h>
#include <stdio.h>

static int check_failures, check_count;

#define CHECK(cond)                                                                           \
    do {                                                                                      \
        check_count++;                                                                        \
        if (!(cond)) {                                                                        \
            check_failures++;                                                                 \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);          \
        }                                                                                     \
    } while (0)

/* |got - want| <= rel * |want| + abs_tol, printing both on failure */
#define CHECK_NEAR(got, want, rel, abs_tol)                                                   \
    do {                                                                                      \
        double g_ = (got), w_ = (want);                                                       \
        check_count++;                                                                        \
        if (!(fabs(g_ - w_) <= (rel) * fabs(w_) + (abs_tol))) {                               \
            check_failures++;                                                                 \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.17g, want %.17g (diff %.3g)\n", \
                    __FILE__, __LINE__, #got, g_, w_, g_ - w_);                               \
        }                                                                                     \
    } while (0)

#define CHECK_DONE()                                                                          \
    do {                                                                                      \
        printf("%d checks, %d failed\n", check_count, check_failures);                        \
        return check_failures ? 1 : 0;                                                        \
    } while (0)

#endif
