/* err: the error rule in code (docs/core.md, "Errors: one rule"): fail with errno in one line,
 * unwind without losing it. */
#ifndef MARIE_ERR_H
#define MARIE_ERR_H

#include <errno.h>
#include <stddef.h>

/* errno = err; returns -1: `return marie_fail(EINVAL);`. */
static inline int marie_fail(int err)
{
    errno = err;
    return -1;
}

/* errno = err; returns NULL: how a constructor refuses, `return marie_fail_null(ENOMEM);`. */
static inline void *marie_fail_null(int err)
{
    errno = err;
    return NULL;
}

/* Runs stmt (a close, a free, an unlink on an error path) and leaves errno as it was before. */
#define MARIE_KEEP_ERRNO(stmt) \
    do { \
        int marie_saved_errno_ = errno; \
        stmt; \
        errno = marie_saved_errno_; \
    } while (0)

#endif
