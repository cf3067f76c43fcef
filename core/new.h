/* new: an object made on the heap whole, from a designated initializer, in one expression. */
#ifndef MARIE_NEW_H
#define MARIE_NEW_H

#include <stdlib.h>
#include <string.h>

/* A copy of the n bytes at src in fresh memory (free() it), or NULL with errno ENOMEM. */
static inline void *marie_memdup(const void *src, size_t n)
{
    void *p = malloc(n);
    return p ? memcpy(p, src, n) : NULL;
}

/* MARIE_NEW(T, .a = 1, .b = x): a T on the heap with those fields and every other one zero (as
 * calloc), or NULL with errno ENOMEM. C only (a compound literal); the temporary is on the stack,
 * so for objects of a few kilobytes. */
#define MARIE_NEW(type, ...) ((type *)marie_memdup(&(type){ __VA_ARGS__ }, sizeof(type)))

#endif
