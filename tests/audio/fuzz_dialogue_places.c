/* fuzz_dialogue_places: arbitrary text as marie-dialogue's `places` parameter, and arbitrary
 * words as what was heard, must parse or be refused, never crash or overflow. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/dialogue/dialogue.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0;
    dialogue_place_t places[DIALOGUE_MAX_PLACES];
    int n = -1;
    char why[128];
    if (dialogue_places_parse(text, places, DIALOGUE_MAX_PLACES, &n, why, sizeof(why)) == 0 &&
        (n < 0 || n > DIALOGUE_MAX_PLACES))
        abort();
    dialogue_t d;
    dialogue_init(&d, places, n > 0 ? n : 0, "x");
    dialogue_reply_t r;
    dialogue_hear(&d, text, 1, true, 0.5, &r);
    if (strlen(r.say) >= sizeof(r.say))
        abort();
    free(text);
    return 0;
}
