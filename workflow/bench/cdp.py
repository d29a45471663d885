"""Headless Chromium driven through the DevTools protocol over a pipe — no package beyond the standard library.

``chromium --remote-debugging-pipe`` reads commands from fd 3 and writes
answers and events to fd 4, each a JSON message ending in NUL
(https://chromedevtools.github.io/devtools-protocol/). :class:`Chromium`
starts a browser on ``about:blank``, attaches to its page (flat session) and
offers :meth:`Chromium.call`; events that arrive meanwhile are kept in
``events``. Used by workflow/bench/viewer3d_compare.py and the browser tests (through viewer3d_compare.open_page).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import time

#: Software WebGL (SwiftShader), local files readable, no name resolution (offline).
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", "--allow-file-access-from-files", "--no-first-run",
         "--host-resolver-rules=MAP * ~NOTFOUND", "--hide-scrollbars", "--remote-debugging-pipe"]


class Chromium:
    """Headless Chromium driven through the DevTools protocol over a pipe (fds 3/4)."""

    def __init__(self, size=(1000, 700)):
        exe = os.environ.get("CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
        if exe is None:
            raise SystemExit("error: no chromium on the path (make test-browser installs it)")
        cmd_r, self._w = os.pipe()
        self._r, res_w = os.pipe()

        def fds():  # in the child: the pipe ends as fds 3 and 4, inheritable (dup2 onto itself would keep CLOEXEC)
            a, b = os.dup(cmd_r), os.dup(res_w)
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.proc = subprocess.Popen([exe, *FLAGS, f"--window-size={size[0]},{size[1]}", "about:blank"],
                                     close_fds=False, preexec_fn=fds,  # fds 3/4 must survive the exec
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(cmd_r)
        os.close(res_w)
        self._id, self._buf, self.events, self.session = 0, b"", [], None
        target = next(t for t in self.call("Target.getTargets")["targetInfos"] if t["type"] == "page")
        self.session = self.call("Target.attachToTarget", targetId=target["targetId"], flatten=True)["sessionId"]

    def call(self, method: str, **params) -> dict:
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if self.session and not method.startswith("Target."):
            msg["sessionId"] = self.session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        while True:
            m = self._next(30.0)
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def _next(self, timeout: float) -> dict:
        end = time.monotonic() + timeout
        while b"\0" not in self._buf:
            if time.monotonic() > end:
                raise TimeoutError("no answer from chromium")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the pipe")
            self._buf += chunk
        line, self._buf = self._buf.split(b"\0", 1)
        return json.loads(line)

    def close(self):
        self.proc.terminate()
        self.proc.wait(timeout=20)
        os.close(self._w)
        os.close(self._r)
