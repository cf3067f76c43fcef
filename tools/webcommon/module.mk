# tools/webcommon: what the web pages' servers share (marie-viewer-server, marie-face): the
# server on the component's loop (webserve.c, its HTTP and WebSocket parsers webproto.c),
# messages as JSON and the pages' commands (vjson.c). Each tool links these sources itself
# (this fragment is read after some of theirs); the shared unit tests live with the viewer's.
