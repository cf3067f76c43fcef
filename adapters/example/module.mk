# adapters/example: the producer/consumer pair that shows the component lifecycle.
$(eval $(call marie_program,marie-example-producer,adapters/example/producer.c))
$(eval $(call marie_program,marie-example-consumer,adapters/example/consumer.c))
