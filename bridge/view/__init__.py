"""`touchswarm view`: a live view of a mission in the browser (docs/view.md).

sources.py  what is shown: a simulated run the server steps, or a host journal
server.py   the HTTP server on 127.0.0.1 (standard library), JSON endpoints
static/     the page: one HTML file and one script, drawing on a <canvas>
browser.py  headless chromium through selenium, for the tests and screenshots
"""
