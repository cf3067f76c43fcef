/* pgm: pure parser for binary (P5) and ASCII (P2) portable graymaps, as map_server writes them. */
#ifndef MARIE_MAP_PGM_H
#define MARIE_MAP_PGM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Largest image side accepted; a bigger header is treated as corrupt, not allocated. */
#define PGM_MAX_SIDE 20000

typedef struct {
    int width, height;
    int maxval;                 /* 1..65535 */
    uint16_t *pixels;           /* width*height, row 0 is the top row; caller frees */
} pgm_t;

/* Parse a whole PGM file held in buf. 0 on success (free out->pixels), or -1 with errno EINVAL with a
 * one-line reason in err (including the byte offset when it helps). */
int pgm_parse(const uint8_t *buf, size_t len, pgm_t *out, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif
