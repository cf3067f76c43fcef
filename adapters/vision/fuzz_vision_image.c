/* fuzz_vision_image: arbitrary bytes as a marie.image_t (format, size, stride from a small
 * header, the rest as pixels or JPEG) must decode or be refused, never crash or leak. */
#include <stdint.h>
#include <string.h>

#include "camera/vision_image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 7)
        return 0;
    marie_image_t img = {
        .format = (int8_t)(data[0] % 5),
        .width = data[1] | (data[2] & 0x3f) << 8,
        .height = data[3] | (data[4] & 0x3f) << 8,
        .row_stride = data[5] | data[6] << 8,
        .size = (int32_t)(size - 7),
        .data = (uint8_t *)data + 7,
    };
    vision_frame_t f = { 0 };
    vision_image_decode(&img, &f, NULL);
    /* The frame stays reusable after a refusal. */
    img.width = img.height = 0;
    vision_image_decode(&img, &f, NULL);
    vision_frame_free(&f);
    return 0;
}
