# tests/arch: the architecture rules of docs/architecture.md, checked on the sources.
ITESTS += tests/arch/test_include_rules.sh
ITESTS += tests/arch/test_commit_messages.sh
