/* lcmcheck: a bounds walk over an encoded LCM message, driven by a layout string. */
#include "managers/lcmcheck.h"

#include <errno.h>
#include <string.h>

typedef struct {
    const uint8_t *p;
    size_t left;
    int depth;
} walk_t;

static int take(walk_t *w, size_t n)
{
    if (n > w->left)
        return -1;
    w->p += n;
    w->left -= n;
    return 0;
}

static int32_t get_i32(const uint8_t *p)
{
    return (int32_t)((uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]);
}

/* Walk layout[0..end) once. */
static int walk(walk_t *w, const char *layout, size_t end)
{
    int32_t last_count = -1;
    for (size_t i = 0; i < end; i++) {
        char c = layout[i];
        switch (c) {
        case 'b': if (take(w, 1)) return -1; break;
        case 'h': if (take(w, 2)) return -1; break;
        case 'f': if (take(w, 4)) return -1; break;
        case 'l': case 'd': if (take(w, 8)) return -1; break;
        case 'i':
            if (w->left < 4)
                return -1;
            last_count = get_i32(w->p);
            take(w, 4);
            break;
        case 's': {
            if (w->left < 4)
                return -1;
            int32_t n = get_i32(w->p);
            take(w, 4);
            /* length counts the terminating NUL, which must be there */
            if (n < 1 || (size_t)n > w->left || w->p[n - 1] != 0)
                return -1;
            take(w, (size_t)n);
            break;
        }
        case '[': {
            size_t close = i + 1;
            int nest = 1;
            while (close < end && nest) {
                if (layout[close] == '[') nest++;
                if (layout[close] == ']') nest--;
                if (nest) close++;
            }
            if (nest || last_count < 0 || w->depth > 8)
                return -1;
            /* every element takes at least one byte: a count beyond the rest is a lie */
            if ((size_t)last_count > w->left && close > i + 1)
                return -1;
            w->depth++;
            for (int32_t k = 0; k < last_count; k++)
                if (walk(w, layout + i + 1, close - i - 1) < 0)
                    return -1;
            w->depth--;
            last_count = -1;
            i = close;
            break;
        }
        default:
            return -1;
        }
    }
    return 0;
}

int marie_lcm_check(const void *buf, size_t len, const char *layout)
{
    walk_t w = {buf, len, 0};
    if (take(&w, 8) < 0)
        return -EBADMSG;
    /* liblcm publishes exactly the encoded size: trailing bytes mean a malformed message */
    return walk(&w, layout, strlen(layout)) == 0 && w.left == 0 ? 0 : -EBADMSG;
}
