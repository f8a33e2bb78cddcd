"""A headless Chromium driven over the DevTools protocol on a pipe (no Python package
needed): load a local page, collect what the browser reported (console messages, log
entries, exceptions, requests), evaluate an expression, take a full-page screenshot.

:func:`find_chromium` gives the binary (``$CHROMIUM``, else ``chromium``,
``chromium-browser``, ``google-chrome`` on the PATH) or None: the tests skip without it.
The browser runs with an empty profile, no background networking and every host name
mapped to 'not found', so a page that tried to reach the network would fail visibly.
"""
import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-extensions", "--host-resolver-rules=MAP * ~NOTFOUND",
         "--remote-debugging-pipe")


def find_chromium():
    env = os.environ.get("CHROMIUM")
    if env:
        return env if os.path.isfile(env) else shutil.which(env)
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


class Browser:
    """``with Browser() as b: page = b.load(path)``; raises RuntimeError on a protocol
    error or a timeout."""

    def __init__(self, binary=None, timeout_s=60.0):
        self.binary = binary or find_chromium()
        self.timeout_s = timeout_s

    def __enter__(self):
        self._profile = tempfile.mkdtemp(prefix="chromium-profile-")
        to_chrome_r, self._w = os.pipe()
        self._r, from_chrome_w = os.pipe()
        # the child's ends above 9, so that moving them to 3 and 4 cannot clobber them
        ends = []
        for fd in (to_chrome_r, from_chrome_w):
            ends.append(fcntl.fcntl(fd, fcntl.F_DUPFD, 10))
            os.close(fd)
        to_chrome_r, from_chrome_w = ends
        # the protocol's fds are 3 (commands in) and 4 (replies out) in the browser
        cmd = [shutil.which("bash") or "/bin/bash", "-c",
               f'exec "$0" "$@" 3<&{to_chrome_r} 4>&{from_chrome_w} '
               f"{to_chrome_r}<&- {from_chrome_w}>&-",
               self.binary, *FLAGS, f"--user-data-dir={self._profile}", "about:blank"]
        self._proc = subprocess.Popen(cmd, pass_fds=(to_chrome_r, from_chrome_w),
                                      stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._buf = b""
        self._id = 0
        self.events = []
        return self

    def __exit__(self, *exc):
        try:
            self._send("Browser.close", wait=False)
            self._proc.wait(timeout=15)
        except Exception:
            self._proc.kill()
            self._proc.wait()
        for fd in (self._r, self._w):
            try:
                os.close(fd)
            except OSError:
                pass
        self.stderr = self._proc.stderr.read().decode(errors="replace")
        self._proc.stderr.close()
        shutil.rmtree(self._profile, ignore_errors=True)

    # the protocol: JSON messages, each ended by a NUL byte
    def _send(self, method, params=None, session=None, wait=True):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        if not wait:
            return None
        want = self._id
        while True:
            reply = self._next()
            if reply.get("id") == want:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def _next(self):
        deadline = time.monotonic() + self.timeout_s
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._r], [], [], left)[0]:
                raise RuntimeError("no reply from the browser within the timeout")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError("the browser closed its DevTools pipe")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        return json.loads(raw)

    def _wait_event(self, method, session):
        while True:
            ev = self._next()
            self.events.append(ev)
            if ev.get("method") == method and ev.get("sessionId") == session:
                return ev

    def load(self, path, expression=None, screenshot=None, width=1200):
        """Open the file ``path``; returns a dict: ``console`` (messages of type error or
        warning), ``log`` (log entries of level error or warning), ``exceptions``,
        ``requests`` (every URL the page asked for), ``value`` (of ``expression``,
        evaluated after the load event).  ``screenshot``: a PNG of the whole page."""
        target = self._send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self._send("Target.attachToTarget", {"targetId": target,
                                                       "flatten": True})["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self._send(f"{domain}.enable", session=session)
        start = len(self.events)
        url = "file://" + os.path.abspath(path)
        self._send("Page.navigate", {"url": url}, session=session)
        self._wait_event("Page.loadEventFired", session)
        value = None
        if expression:
            res = self._send("Runtime.evaluate", {"expression": expression,
                                                  "returnByValue": True}, session=session)
            if "exceptionDetails" in res:
                raise RuntimeError(f"evaluate: {res['exceptionDetails']}")
            value = res["result"].get("value")
        if screenshot:
            self._send("Emulation.setDeviceMetricsOverride",
                       {"width": width, "height": 900, "deviceScaleFactor": 1,
                        "mobile": False}, session=session)
            size = self._send("Page.getLayoutMetrics", session=session)["cssContentSize"]
            shot = self._send("Page.captureScreenshot", {
                "format": "png", "captureBeyondViewport": True,
                "clip": {"x": 0, "y": 0, "width": width, "height": size["height"],
                         "scale": 1}}, session=session)
            with open(screenshot, "wb") as f:
                f.write(base64.b64decode(shot["data"]))
        time.sleep(0.3)               # late log entries of the load
        self._send("Runtime.evaluate", {"expression": "1"}, session=session)
        events = [e for e in self.events[start:] if e.get("sessionId") == session]
        self._send("Target.closeTarget", {"targetId": target})
        return {
            "console": [e["params"] for e in events if e.get("method") ==
                        "Runtime.consoleAPICalled" and e["params"]["type"] in
                        ("error", "warning", "assert")],
            "log": [e["params"]["entry"] for e in events if e.get("method") ==
                    "Log.entryAdded" and e["params"]["entry"]["level"] in
                    ("error", "warning")],
            "exceptions": [e["params"] for e in events
                           if e.get("method") == "Runtime.exceptionThrown"],
            "requests": [e["params"]["request"]["url"] for e in events
                         if e.get("method") == "Network.requestWillBeSent"],
            "failed": [e["params"] for e in events
                       if e.get("method") == "Network.loadingFailed"],
            "value": value}
