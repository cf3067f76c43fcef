/* micarray: a microphone array's geometry (robot frame, m), parsed from one text parameter
 * shared by the simulator and marie-ssl so that both agree on where each channel is. */
#ifndef MARIE_HW_AUDIO_MICARRAY_H
#define MARIE_HW_AUDIO_MICARRAY_H

#ifdef __cplusplus
extern "C" {
#endif

#define MICARRAY_MAX 16

/* Eight microphones on a 0.16 m circle, 45 degrees apart from straight ahead, at heights
 * alternating 0.60 and 0.70 m so that the array also resolves elevation. */
#define MICARRAY_DEFAULT "0.16,0,0.6;0.1131,0.1131,0.7;0,0.16,0.6;-0.1131,0.1131,0.7;" \
                         "-0.16,0,0.6;-0.1131,-0.1131,0.7;0,-0.16,0.6;0.1131,-0.1131,0.7"

typedef struct {
    int n;
    double pos[MICARRAY_MAX][3];
    double center[3];
} micarray_t;

/* "x,y,z;x,y,z;..." (2 to MICARRAY_MAX microphones, |coordinate| <= 10 m). 0, or -1 with
 * errno EINVAL and a reason in why (may be NULL). */
int micarray_parse(const char *text, micarray_t *out, const char **why);

/* Largest distance between two microphones, m. */
double micarray_aperture(const micarray_t *a);

#ifdef __cplusplus
}
#endif
#endif
