# tools/map: marie-map, behind `marie map save NAME` (the live map as a map_server pair), `marie map
# compare` and `marie map eval` (a recorded run's poses against a reference, and its picture).
$(eval $(call marie_program,marie-map,tools/map/map_main.c tools/map/map_eval.c tools/map/map_picture.cpp,$(MAP_LIB) $(shell pkg-config --libs opencv4 2>/dev/null)))
$(B)/obj/tools/map/map_picture.o: CXXFLAGS += $(shell pkg-config --cflags opencv4 2>/dev/null)
