/* xb_canon: canonical "path=value" lines of a message, so two decoders can be compared field by
 * field; and a generator of sample messages of any type with their canonical lines. */
#ifndef XB_CANON_H
#define XB_CANON_H

#include <stdint.h>

#include "adapters/xml_bridge/xb_codec.h"

typedef struct {
    marie_buf_t buf;
} xb_canon_t;

void xb_canon_init(xb_canon_t *d);
void xb_canon_free(xb_canon_t *d);
void xb_canon_int(xb_canon_t *d, const char *path, long long v);
void xb_canon_float(xb_canon_t *d, const char *path, float v);
void xb_canon_double(xb_canon_t *d, const char *path, double v);
void xb_canon_str(xb_canon_t *d, const char *path, const char *s);
const char *xb_canon_text(xb_canon_t *d);        /* NUL-terminated */

/* Generated from lcmtypes/ (build/gen/xml_bridge/xb_structdump.c): prints an lcm-gen C struct
 * of the named type. 0, or -1 for an unknown type. */
int xb_struct_dump(xb_canon_t *d, const char *type, const void *msg);

/* A pseudo-random message of type t (seeded): the XML of its fields (children of a <message>
 * element, length fields sometimes left out) and its canonical lines. */
void xb_sample(const marie_typeinfo_t *t, uint32_t seed, marie_buf_t *xml, xb_canon_t *canon);

#endif
