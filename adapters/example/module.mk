# adapters/example: the producer/consumer pair that shows the component lifecycle.
$(eval $(call marie_program,marie-example-producer,adapters/example/producer.c))
$(eval $(call marie_program,marie-example-consumer,adapters/example/consumer.c))
# The same pair in Python (python/marie), with a pull port on the Mailbox.
$(eval $(call marie_py_program,marie-example-producer-py,adapters/example/py/producer.py))
$(eval $(call marie_py_program,marie-example-consumer-py,adapters/example/py/consumer.py))
