# tools/topic: marie-topic (`marie topic list|echo|hz|pub`), on the viewer's JSON walker.
$(eval $(call marie_program,marie-topic,tools/topic/topic_main.c tools/topic/topic_encode.c tools/webcommon/vjson.c))
# marie-param (`marie param list|get|set`): parameters of running components.
$(eval $(call marie_program,marie-param,tools/topic/param_main.c))
ITESTS += tests/tools/test_topic_param.sh
