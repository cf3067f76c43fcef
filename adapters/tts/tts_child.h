/* tts_child: one synthesis by an external synthesizer process (Festival's text2wave): text on
 * its stdin, a WAVE stream read from its stdout through the component's loop, so the loop never
 * blocks while Festival works and a stuck synthesis can be killed. */
#ifndef MARIE_TTS_CHILD_H
#define MARIE_TTS_CHILD_H
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "core/loop.h"

typedef struct tts_child tts_child_t;

/* Called once: pcm (mono 16-bit at rate) and n samples, or NULL with a reason. */
typedef void (*tts_child_done_cb_t)(const int16_t *pcm, size_t n, int rate, const char *why, void *user);

/* argv: the command (NULL-terminated). NULL with errno when it cannot be started. */
tts_child_t *tts_child_start(marie_loop_t *loop, char *const argv[], const char *text,
                             tts_child_done_cb_t cb, void *user);
/* Kills a synthesis in progress (no callback); NULL is a no-op. */
void tts_child_cancel(tts_child_t *t);

#endif
