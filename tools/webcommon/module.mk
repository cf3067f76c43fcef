# tools/webcommon: what the web pages' servers share (marie-viewer-server, marie-face):
# civetweb with one WebSocket writer per page (webserve.c), messages as JSON and the pages'
# commands (vjson.c). Each tool links these sources itself (this fragment is read after
# some of theirs); the shared unit tests live with the viewer's.
