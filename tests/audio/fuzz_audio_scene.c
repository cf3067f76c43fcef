/* fuzz_audio_scene: arbitrary text as the simulator's `audio` scene must parse or be refused
 * with a reason, and a parsed scene stays within its documented bounds. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sim/audio.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0;
    sim_audio_scene_t sc;
    char why[128];
    if (sim_audio_scene_parse(text, &sc, why, sizeof(why)) == 0) {
        if (sc.n < 0 || sc.n > SIM_AUDIO_MAX_SOURCES || !(sc.reflect >= 0 && sc.reflect < 1))
            abort();
        for (int i = 0; i < sc.n; i++)
            if (!isfinite(sc.src[i].x) || !(sc.src[i].level >= 0) || strlen(sc.src[i].file) >= sizeof(sc.src[i].file))
                abort();
    } else if (!why[0]) {
        abort();
    }
    free(text);
    return 0;
}
