/* typeinfo: descriptors of every marie LCM type (generated from the .lcm files in lcmtypes/ by
 * lcmtypes/typeinfo_gen.py) and a checker of payloads against them. */
#ifndef MARIE_TYPEINFO_H
#define MARIE_TYPEINFO_H

#include <stddef.h>
#include <stdint.h>

#include "lcmtypes/marie_types.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    MARIE_PRIM_INT8, MARIE_PRIM_INT16, MARIE_PRIM_INT32, MARIE_PRIM_INT64, MARIE_PRIM_BYTE, MARIE_PRIM_FLOAT, MARIE_PRIM_DOUBLE, MARIE_PRIM_STRING, MARIE_PRIM_BOOL,
    MARIE_PRIM_STRUCT,
} marie_prim_t;

/* One array dimension: a fixed size, or the index of an earlier integer field holding it. */
typedef struct {
    int32_t size;           /* fixed size when len_field < 0 */
    int16_t len_field;
} marie_tdim_t;

typedef struct marie_typeinfo marie_typeinfo_t;

typedef struct {
    const char *name;
    marie_prim_t prim;
    const marie_typeinfo_t *sub;     /* MARIE_PRIM_STRUCT only */
    int ndims;
    const marie_tdim_t *dims;       /* ndims entries, outermost first */
    size_t c_offset;                /* where lcm-gen's C struct holds it (offsetof) */
    int flags;                      /* MARIE_TFIELD_* */
} marie_tfield_t;

/* The field's NaN and infinities have a meaning (its .lcm line says @nonfinite: a laser's ranges,
 * REP 117), so MARIE_CHECK_FINITE lets them through. */
#define MARIE_TFIELD_NONFINITE 1

typedef struct {
    const char *name;
    marie_prim_t prim;
    const char *value;          /* as written in the .lcm file */
} marie_tconst_t;

struct marie_typeinfo {
    const char *name;           /* "marie.pose_cov_t" */
    const char *short_name;     /* "pose_cov_t" */
    int64_t fingerprint;        /* as lcm-gen computes it, written first on the wire */
    int nfields;
    const marie_tfield_t *fields;
    int nconsts;
    const marie_tconst_t *consts;
};

/* Every struct of lcmtypes/, sorted by name, NULL-terminated. */
extern const marie_typeinfo_t *const marie_typeinfos[];
extern const size_t marie_typeinfos_count;

/* A user's types, made by marie-types-gen from .lcm files outside marie (docs/types.md): their
 * codecs and descriptors. Once registered, every lookup below finds them as it finds marie's own,
 * so typed ports, checked decode, the XML bridge, the viewer and the command line handle them. */
#define MARIE_TYPES_MODULE_VERSION 1
typedef struct {
    int version;                                /* MARIE_TYPES_MODULE_VERSION */
    const char *name;                           /* "ux" */
    const marie_type_t *const *types;           /* NULL-terminated */
    const marie_typeinfo_t *const *infos;       /* NULL-terminated: the same types' descriptors */
} marie_types_module_t;
/* Register a module (kept, not copied; at start-up, before any thread reads the tables). A type
 * whose name or fingerprint is already known is skipped: the first registered wins. 0, or -1 with
 * errno EINVAL (another version) or ENOSPC (too many modules). A module registered twice is
 * registered once. */
int marie_types_register(const marie_types_module_t *m);
/* The i-th known type: marie's own (marie_typeinfos order), then the registered modules'; NULL
 * past the last. For listings (the XML bridge's <types/>, marie topic). */
const marie_typeinfo_t *marie_typeinfo_at(size_t i);
/* Load what marie-types-gen made: a shared library (its `marie_types_module` symbol), or an output
 * directory (every lib/libmarie-types-*.so in it). A relative path is taken from `base_dir` when
 * not NULL. 0, or -1 with errno and a one-line reason in why. */
int marie_types_load(const char *path, const char *base_dir, char *why, size_t whylen);
/* marie_types_load() for each entry of a colon-separated list (MARIE_TYPES_PATH); an empty or
 * NULL list loads nothing. Stops at the first failure, with its reason. */
int marie_types_load_list(const char *list, char *why, size_t whylen);

/* By full ("marie.pose_cov_t") or short name ("pose_cov_t"); NULL if unknown. */
const marie_typeinfo_t *marie_typeinfo_find(const char *name);
/* By wire fingerprint; NULL if unknown. */
const marie_typeinfo_t *marie_typeinfo_by_fingerprint(int64_t fp);
const char *marie_prim_name(marie_prim_t p);   /* "int32_t", ..., "struct" */
/* Bytes a primitive takes on the wire (0 for strings and structs). */
int marie_prim_size(marie_prim_t p);
/* A big-endian signed integer of n (1..8) bytes, as LCM writes them. */
int64_t marie_wire_int(const uint8_t *p, int n);

/* Checks that buf holds exactly one well-formed payload of type t (fingerprint first): every
 * string is NUL-terminated within its length, every array count is non-negative and fits the
 * payload, and nothing trails it. lcm-gen's C decoders trust lengths, so nothing from the bus
 * is decoded before this passes. Returns 0, or -1 with errno EBADMSG. */
int marie_typeinfo_check(const marie_typeinfo_t *t, const void *buf, size_t len);

/* marie_typeinfo_check() with options: MARIE_CHECK_FINITE also walks every float and double
 * (scalars, arrays, nested structs; not the fields marked MARIE_TFIELD_NONFINITE) and returns
 * fails with EDOM when one is NaN or infinite. */
#define MARIE_CHECK_FINITE 1
int marie_typeinfo_check_flags(const marie_typeinfo_t *t, const void *buf, size_t len, int flags);

/* A type that ends in a byte array after fields of fixed size only (scalars, or structs of them:
 * image_t's pixels, occupancy_grid_t's cells): where the array's bytes and its int32 length lie
 * on the wire and in lcm-gen's C struct, so that the bytes can be written apart from the other
 * fields (a loaned publish, core/component.h). */
typedef struct {
    size_t wire_off;            /* the array's first byte on the wire, fingerprint included */
    size_t len_wire_off;        /* its length on the wire */
    size_t ptr_off, len_off;    /* the array's pointer and its length in the C struct */
} marie_tail_t;
/* 0, or -1 with errno ENOTSUP for a type of any other shape. */
int marie_typeinfo_tail(const marie_typeinfo_t *t, marie_tail_t *out);

/* The registered type called `name` ("marie.pose2d_t", or "pose2d_t"), or NULL. */
const marie_type_t *marie_type_find(const char *name);
/* The registered type whose fingerprint is `fp`, or NULL. */
const marie_type_t *marie_type_by_fingerprint(int64_t fp);
/* The big-endian fingerprint that starts every LCM payload; 0 when len < 8. */
int64_t marie_payload_fingerprint(const void *buf, size_t len);

/* Check a payload of the registered type t, then decode it into out (zeroed first; free with
 * t->decode_cleanup). 0, or -1 with errno EBADMSG. Every decoder of bus input calls this. */
int marie_decode_checked(const marie_type_t *t, const void *buf, size_t len, void *out);

/* What a component does with an input message (ports, pull replies, raw subscriptions): as
 * marie_decode_checked(), and a NaN or infinity in any float or double field is refused too,
 * but in the fields that give them a meaning (MARIE_TFIELD_NONFINITE; see docs/core.md). On failure *why (if why is not NULL)
 * names the bad-input counter: "bad_fingerprint", "bad_payload" or "bad_nonfinite". 0,
 * or -1 with errno EBADMSG, or EDOM (non-finite). */
int marie_decode_input(const marie_type_t *t, const void *buf, size_t len, void *out, const char **why);
/* As marie_decode_input(), without copying a type's tail (marie_typeinfo_tail: image_t's
 * pixels, occupancy_grid_t's cells): its pointer aims into buf, so `out` is valid only while
 * buf's bytes stay as they are (a slot held in shared memory). 1 when the tail aims into buf, 0
 * when the type has another shape and was decoded whole, or -1 with errno as
 * marie_decode_input(). Free with marie_decode_cleanup_view(t, out, what it returned). */
int marie_decode_view(const marie_type_t *t, const void *buf, size_t len, void *out, const char **why);
void marie_decode_cleanup_view(const marie_type_t *t, void *out, int viewed);

#ifdef __cplusplus
}
#endif
#endif
