/* marie-vision: AprilTag tracking and message reading from a camera, a file or the bus. */
#include "adapters/vision/vision_component.h"

int main(int argc, char **argv)
{
    return marie_main(&vision_component_def, argc, argv, NULL);
}
