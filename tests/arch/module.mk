# tests/arch: the architecture rules of docs/architecture.md, checked on the sources.
ITESTS += tests/arch/test_include_rules.sh
ITESTS += tests/arch/test_commit_messages.sh
ITESTS += tests/arch/test_bus_rules.sh tests/arch/test_file_lengths.sh
ITESTS += tests/arch/test_params_once.sh tests/arch/test_error_rule.sh
