/* vision_component: the marie-vision Application Adapter (camera -> AprilTags -> tracks,
 * detections, messages and goals), as a component definition for marie_main. */
#ifndef VISION_COMPONENT_H
#define VISION_COMPONENT_H

#include "core/component.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Default channels of its ports. */
#define VISION_CH_IMAGE      "CAMERA_IMAGE"
#define VISION_CH_DETECTIONS "TAG_DETECTIONS"
#define VISION_CH_GOAL       "GOAL"
#define VISION_CH_POSE       "POSE"
#define VISION_CH_LANDMARKS  "LANDMARKS"

extern const marie_component_def_t vision_component_def;

#ifdef __cplusplus
}
#endif
#endif
