/* fails: a cmocka check of the error rule (-1 with errno) in one line. */
#ifndef MARIE_TESTS_FAILS_H
#define MARIE_TESTS_FAILS_H

#include <errno.h>

/* expr returns -1 and leaves errno at err: `assert_fails(marie_loop_remove_fd(l, 7), ENOENT);` */
#define assert_fails(expr, err) \
    do { \
        errno = 0; \
        long long fails_rc_ = (long long)(expr); \
        int fails_errno_ = errno; \
        assert_int_equal(fails_rc_, -1); \
        assert_int_equal(fails_errno_, (err)); \
    } while (0)

#endif
