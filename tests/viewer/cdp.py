"""cdp: drives a headless Chromium over the DevTools protocol (its remote debugging port), so a
test waits in real time for a page to reach a state instead of guessing a time budget.
  python3 tests/viewer/cdp.py --port 9222 URL [--until JS] [--timeout S] [--dom FILE]
                              [--screenshot FILE] [--size WxH] [--then CMD --until2 JS]
                              [--do JS --until2 JS]
                              [--eval JS --eval-out FILE] [--touch] [--tap SELECTOR]
Opens URL in a new tab, waits until the JS expression is true (default: the viewer page says
it has settled), then writes the DOM and/or a PNG. Exit 0 when the condition held, 1 on a
timeout (the DOM is still written, to show what the page said). With --then, once the first
condition holds the shell command runs and the page must then reach --until2 (a server
killed under a connected page, for instance); --do runs a script in the page instead (a
click).  --eval writes the JSON value of an expression
(the layout of an element, say) evaluated when the screenshot is taken. --touch emulates a
touch screen; --tap SELECTOR, once the first condition holds, touches the element's centre
with a touch start and end (Input.dispatchTouchEvent), as a finger would."""
import argparse
import base64
import json
import subprocess
import sys
import time
import urllib.request

sys.path.insert(0, "tests/viewer")
from wsclient import WsClient  # noqa: E402


class Tab:
    def __init__(self, port):
        self.port = port
        req = urllib.request.Request("http://127.0.0.1:%d/json/new?about:blank" % port, method="PUT")
        info = json.loads(urllib.request.urlopen(req, timeout=10).read())
        self.id = info["id"]
        path = info["webSocketDebuggerUrl"].split(str(port), 1)[1]
        self.ws = WsClient("127.0.0.1", port, path=path, timeout=30)
        self.next = 0

    def call(self, method, **params):
        self.next += 1
        mid = self.next
        self.ws.send({"id": mid, "method": method, "params": params})
        while True:
            m = self.ws.recv_json()
            if m is None:
                raise ConnectionError("DevTools connection closed")
            if m.get("id") == mid:
                if "error" in m:
                    raise RuntimeError("%s: %s" % (method, m["error"]))
                return m.get("result", {})

    def eval(self, expr):
        r = self.call("Runtime.evaluate", expression=expr, returnByValue=True)
        return r.get("result", {}).get("value")

    def close(self):
        try:
            self.ws.close()
            urllib.request.urlopen("http://127.0.0.1:%d/json/close/%s" % (self.port, self.id), timeout=5).read()
        except Exception:
            pass


def wait(tab, expr, timeout):
    end = time.time() + timeout
    while time.time() < end:
        try:
            if tab.eval("(function(){try{return %s}catch(e){return false}})()" % expr):
                return True
        except RuntimeError:
            pass
        time.sleep(0.1)
    print("cdp: timed out waiting for: %s" % expr, file=sys.stderr)
    return False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("url")
    ap.add_argument("--port", type=int, default=9222)
    ap.add_argument("--until", default="document.body.dataset.settled === '1'")
    ap.add_argument("--timeout", type=float, default=20)
    ap.add_argument("--dom")
    ap.add_argument("--screenshot")
    ap.add_argument("--size", default="1280x900")
    ap.add_argument("--do")
    ap.add_argument("--then")
    ap.add_argument("--until2")
    ap.add_argument("--eval")
    ap.add_argument("--eval-out")
    ap.add_argument("--touch", action="store_true")
    ap.add_argument("--tap")
    a = ap.parse_args()
    tab = Tab(a.port)
    w, h = (int(x) for x in a.size.split("x"))
    tab.call("Emulation.setDeviceMetricsOverride", width=w, height=h, deviceScaleFactor=1, mobile=False)
    if a.touch or a.tap:
        tab.call("Emulation.setTouchEmulationEnabled", enabled=True, maxTouchPoints=1)
        tab.call("Emulation.setEmitTouchEventsForMouse", enabled=True, configuration="mobile")
    tab.call("Page.navigate", url=a.url)
    ok = wait(tab, a.until, a.timeout)
    if ok and a.tap:
        box = tab.eval("(function(){var r=document.querySelector(%s).getBoundingClientRect();"
                       "return [r.left + r.width / 2, r.top + r.height / 2]})()" % json.dumps(a.tap))
        pt = [{"x": box[0], "y": box[1]}]
        tab.call("Input.dispatchTouchEvent", type="touchStart", touchPoints=pt)
        tab.call("Input.dispatchTouchEvent", type="touchEnd", touchPoints=[])
    if ok and a.do:
        tab.eval(a.do)
        ok = wait(tab, a.until2 or "true", a.timeout)
    if ok and a.then:
        subprocess.run(a.then, shell=True)
        ok = wait(tab, a.until2 or "true", a.timeout)
    time.sleep(0.1)      # let the last frame paint
    if a.dom:
        with open(a.dom, "w") as f:
            f.write(tab.eval("document.documentElement.outerHTML") or "")
    if a.eval and a.eval_out:
        with open(a.eval_out, "w") as f:
            json.dump(tab.eval(a.eval), f)
    if a.screenshot:
        png = tab.call("Page.captureScreenshot", format="png")["data"]
        with open(a.screenshot, "wb") as f:
            f.write(base64.b64decode(png))
    tab.close()
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
