/* clear: let go of what a pointer field owns and forget it, in one step (GLib's g_clear_pointer). */
#ifndef MARIE_CLEAR_H
#define MARIE_CLEAR_H

/* destroy(ptr), then ptr = NULL; ptr is named twice, so it must be a plain lvalue (s->map), and
 * destroy must take NULL (every marie _destroy does; so does free). */
#define MARIE_CLEAR(ptr, destroy) \
    do { \
        destroy(ptr); \
        (ptr) = NULL; \
    } while (0)

#endif
