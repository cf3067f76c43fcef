# map: libmarie_map, the one occupancy-grid library (map_server files, ray casting, test worlds,
# a live map from the bus)
# under the simulator, the adapters, the viewer and the demo.
MAP_LIB := $(B)/lib/libmarie_map.a
$(eval $(call marie_lib,marie_map,map/pgm.c map/occmap.c map/occmap_load.c map/occmap_save.c map/gridpath.c map/clearance.c map/mapeval.c map/trajeval.c map/livemap.c))
$(eval $(call marie_test,test_map,tests/map/test_map.c,$(MAP_LIB)))
$(eval $(call marie_fuzz,map_pgm,tests/map/fuzz_map_pgm.c map/pgm.c map/occmap.c map/occmap_load.c,))
$(eval $(call marie_test,test_map_save,tests/map/test_map_save.c,$(MAP_LIB)))
$(eval $(call marie_test,test_mapeval,tests/map/test_mapeval.c,$(MAP_LIB)))
$(eval $(call marie_test,test_livemap,tests/map/test_livemap.c,$(MAP_LIB)))
$(eval $(call marie_test,test_trajeval,tests/map/test_trajeval.c,$(MAP_LIB)))
