# tools/map: marie-map, behind `marie map save NAME` (the live map as a map_server pair).
$(eval $(call marie_program,marie-map,tools/map/map_main.c,$(MAP_LIB)))
