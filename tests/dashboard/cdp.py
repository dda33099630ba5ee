"""A minimal Chrome DevTools Protocol client for headless Chromium, standard library only.

The browser is started with --remote-debugging-pipe: it reads NUL-terminated JSON messages on
its fd 3 and writes its answers and events on its fd 4. Everything here is synchronous: a
command is written, then messages are read until its answer arrives; events met on the way
are kept (console errors and uncaught exceptions end up in Browser.console).

    with Browser() as b:
        page = b.new_page(1280, 900)
        page.navigate("http://127.0.0.1:8080/")
        page.wait_for("document.querySelector('#jobs tbody tr') !== null")
        page.screenshot("jobs.png")
"""

import base64
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time

CHROMIUM = "/usr/bin/chromium"


class CDPError(RuntimeError):
    pass


class BrowserUnavailable(RuntimeError):
    """Chromium is missing or did not answer on its debugging pipe."""


# The child end of each pipe has to sit at fds 3 and 4 in Chromium. subprocess closes every fd
# it was not told to keep after running preexec_fn, so the renumbering is done by a tiny Python
# shim that is handed the two fds (pass_fds), moves them and execs Chromium.
_SHIM = (
    "import os, sys\n"
    "r, w = int(sys.argv[1]), int(sys.argv[2])\n"
    "os.dup2(r, 3); os.dup2(w, 4)\n"
    "os.close(r); os.close(w)\n"
    "os.execv(sys.argv[3], sys.argv[3:])\n"
)


def _high_fd(fd: int) -> int:
    """fd moved to >= 10, so that the shim's dup2 onto 3 and 4 cannot clobber the other one."""
    import fcntl

    high = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
    os.close(fd)
    return high


class Browser:
    def __init__(self, chromium: str = CHROMIUM, extra_args=(), timeout_s: float = 30):
        if not os.path.exists(chromium):
            raise BrowserUnavailable(f"{chromium} is missing")
        self.timeout_s = timeout_s
        self.console = []  # "level: text" of console errors and uncaught exceptions, all pages
        self._events = []
        self._next_id = 0
        self._buf = b""
        self._profile = tempfile.mkdtemp(prefix="cdp-profile-")
        args = [
            chromium,
            "--headless=new",
            "--remote-debugging-pipe",
            f"--user-data-dir={self._profile}",
            "--disable-gpu",
            "--no-first-run",
            "--no-default-browser-check",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-extensions",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
            "--mute-audio",
            *extra_args,
        ]
        if os.geteuid() == 0:
            args.append("--no-sandbox")  # Chromium refuses to run as root with its sandbox
        args.append("about:blank")

        to_browser_r, to_browser_w = os.pipe()
        from_browser_r, from_browser_w = os.pipe()
        child_r, child_w = _high_fd(to_browser_r), _high_fd(from_browser_w)
        self._log = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(
                [sys.executable or "/usr/bin/python3", "-c", _SHIM, str(child_r), str(child_w), *args],
                pass_fds=(child_r, child_w),
                stdin=subprocess.DEVNULL,
                stdout=self._log,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # a Ctrl-C of the test reaches us, and we close the browser
            )
        finally:
            os.close(child_r)
            os.close(child_w)
        self._out = to_browser_w
        self._in = from_browser_r
        try:
            self.version = self.send("Browser.getVersion", timeout_s=timeout_s)
        except Exception as e:
            log = self.log_tail()
            self.close()
            raise BrowserUnavailable(f"Chromium did not start: {e}\n{log}") from e

    # -- the pipe ---------------------------------------------------------------------------

    def log_tail(self, n: int = 4000) -> str:
        try:
            self._log.seek(0)
            return self._log.read().decode(errors="replace")[-n:]
        except (OSError, ValueError):
            return ""

    def _write(self, message: dict) -> None:
        data = json.dumps(message).encode() + b"\0"
        while data:
            n = os.write(self._out, data)
            data = data[n:]

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("no message from Chromium in time")
            ready, _, _ = select.select([self._in], [], [], left)
            if not ready:
                continue
            chunk = os.read(self._in, 1 << 20)
            if not chunk:
                raise CDPError("Chromium closed its debugging pipe\n" + self.log_tail())
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        return json.loads(raw)

    def _note(self, message: dict) -> None:
        method = message.get("method", "")
        params = message.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = params.get("exceptionDetails", {})
            text = d.get("exception", {}).get("description") or d.get("text", "")
            self.console.append(f"exception: {text}")
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
            self.console.append(f"console.{params['type']}: {text}")
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            e = params["entry"]
            self.console.append(f"log: {e.get('text', '')} {e.get('url', '')}".rstrip())
        self._events.append(message)
        del self._events[:-1000]

    def send(self, method: str, params: dict = None, session: str = None, timeout_s: float = None):
        """Runs one command and returns its result; raises CDPError on a protocol error."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        self._write(message)
        deadline = time.monotonic() + (timeout_s or self.timeout_s)
        while True:
            answer = self._read(deadline)
            if answer.get("id") == self._next_id:
                if "error" in answer:
                    raise CDPError(f"{method}: {answer['error'].get('message')}")
                return answer.get("result", {})
            if "method" in answer:
                self._note(answer)

    def events(self, method: str, session: str = None) -> list:
        """The kept events of one kind (optionally of one page), oldest first."""
        return [
            e for e in self._events
            if e.get("method") == method and (session is None or e.get("sessionId") == session)
        ]

    # -- pages ------------------------------------------------------------------------------

    def new_page(self, width: int = 1280, height: int = 900) -> "Page":
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        page = Page(self, target, session)
        for domain in ("Page", "Runtime", "Log"):
            page.send(f"{domain}.enable")
        page.resize(width, height)
        return page

    def close(self) -> None:
        if getattr(self, "proc", None) and self.proc.poll() is None:
            try:
                self._write({"id": self._next_id + 1, "method": "Browser.close", "params": {}})
            except OSError:
                pass
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        for fd in ("_out", "_in"):
            if getattr(self, fd, None) is not None:
                try:
                    os.close(getattr(self, fd))
                except OSError:
                    pass
                setattr(self, fd, None)
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Page:
    def __init__(self, browser: Browser, target_id: str, session: str):
        self.browser = browser
        self.target_id = target_id
        self.session = session

    def send(self, method: str, params: dict = None, timeout_s: float = None):
        return self.browser.send(method, params, self.session, timeout_s)

    def resize(self, width: int, height: int) -> None:
        self.send("Emulation.setDeviceMetricsOverride",
                  {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})

    def evaluate(self, expression: str, timeout_s: float = None):
        """The value of a JavaScript expression (promises are awaited), as JSON makes it."""
        r = self.send("Runtime.evaluate",
                      {"expression": expression, "returnByValue": True, "awaitPromise": True,
                       "userGesture": True},
                      timeout_s)
        if "exceptionDetails" in r:
            d = r["exceptionDetails"]
            text = d.get("exception", {}).get("description") or d.get("text", "")
            raise CDPError(f"evaluating {expression[:80]!r}: {text}")
        return r.get("result", {}).get("value")

    def wait_for(self, predicate: str, timeout_s: float = 15, interval_s: float = 0.1):
        """Polls a JavaScript expression until it is truthy; returns its value."""
        deadline = time.monotonic() + timeout_s
        last_error = None
        while True:
            try:
                value = self.evaluate(predicate)
                if value:
                    return value
            except CDPError as e:  # e.g. the document is being replaced
                last_error = e
            if time.monotonic() > deadline:
                raise TimeoutError(f"timed out after {timeout_s} s waiting for: {predicate}"
                                   + (f" (last error: {last_error})" if last_error else ""))
            time.sleep(interval_s)

    def navigate(self, url: str, timeout_s: float = 15) -> None:
        """Loads url and waits until its document has loaded; a change of the fragment only
        fires hashchange, as in a browser."""
        r = self.send("Page.navigate", {"url": url})
        if r.get("errorText"):
            raise CDPError(f"navigating to {url}: {r['errorText']}")
        self.wait_for("document.readyState === 'complete'", timeout_s)

    def insert_text(self, selector: str, text: str) -> None:
        """Focuses an input and types text into it, as a keyboard would (input events fire)."""
        self.evaluate(f"document.querySelector({json.dumps(selector)}).focus()")
        self.send("Input.insertText", {"text": text})

    def screenshot(self, path: str, width: int = None, height: int = None) -> None:
        if width and height:
            self.resize(width, height)
        r = self.send("Page.captureScreenshot", {"format": "png"})
        with open(path, "wb") as f:
            f.write(base64.b64decode(r["data"]))

    def close(self) -> None:
        self.browser.send("Target.closeTarget", {"targetId": self.target_id})
