# deploy: the install layout's generated parts: a man page and a bash completion for every
# program, made from its --help at make install (scripts/gen-man-completion.sh).
INSTALL_EXTRA += scripts/gen-man-completion.sh $(B)/share/help $(PROGRAMS) $(filter $(B)/bin/%,$(EXTRA_TARGETS)) >/dev/null && \
    install -d $(DESTDIR)$(PREFIX)/share/man/man1 $(DESTDIR)$(PREFIX)/share/bash-completion/completions && \
    install -m 644 $(B)/share/help/man1/*.1 $(DESTDIR)$(PREFIX)/share/man/man1/ && \
    install -m 644 $(B)/share/help/completions/* $(DESTDIR)$(PREFIX)/share/bash-completion/completions/;
