/* xb_types: descriptors of every LCM type, generated from the .lcm files of lcmtypes/ by xb_gen.py. */
#ifndef XB_TYPES_H
#define XB_TYPES_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    XB_INT8, XB_INT16, XB_INT32, XB_INT64, XB_BYTE, XB_FLOAT, XB_DOUBLE, XB_STRING, XB_BOOL,
    XB_STRUCT,
} xb_prim_t;

/* One array dimension: a fixed size, or the index of an earlier integer field holding it. */
typedef struct {
    int32_t size;           /* fixed size when len_field < 0 */
    int16_t len_field;
} xb_dim_t;

typedef struct xb_struct xb_struct_t;

typedef struct {
    const char *name;
    xb_prim_t prim;
    const xb_struct_t *sub;     /* XB_STRUCT only */
    int ndims;
    const xb_dim_t *dims;       /* ndims entries, outermost first */
} xb_field_t;

typedef struct {
    const char *name;
    xb_prim_t prim;
    const char *value;          /* as written in the .lcm file */
} xb_const_t;

struct xb_struct {
    const char *name;           /* "marie.pose_cov_t" */
    const char *short_name;     /* "pose_cov_t" */
    int64_t fingerprint;        /* as lcm-gen computes it, written first on the wire */
    int nfields;
    const xb_field_t *fields;
    int nconsts;
    const xb_const_t *consts;
};

/* Every struct of lcmtypes/, sorted by name, NULL-terminated. */
extern const xb_struct_t *const xb_structs[];
extern const size_t xb_structs_count;

/* By full ("marie.pose_cov_t") or short name ("pose_cov_t"); NULL if unknown. */
const xb_struct_t *xb_struct_find(const char *name);
/* By wire fingerprint; NULL if unknown. */
const xb_struct_t *xb_struct_by_fingerprint(int64_t fp);
const char *xb_prim_name(xb_prim_t p);   /* "int32_t", ..., "struct" */

#ifdef __cplusplus
}
#endif
#endif
