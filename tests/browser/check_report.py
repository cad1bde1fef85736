#!/usr/bin/env python3
"""Browser check of a results folder's `report.html` in Debian's headless Chromium, spoken to
over the Chrome DevTools Protocol (the `websocket-client` package, pinned in requirements.txt).

Opens the report from its file:// URL in a 1400 px wide viewport, waits for the load event,
and fails on: an uncaught exception, console.error or console.assert, a browser log entry of
level error (a resource that failed to load, for one), an <img> that did not load or decode
(naturalWidth 0), an outermost inline <svg> whose getBBox is empty, and any request that is
not file:, data:, blob: or about: (the report must be self-contained; Chromium runs with a
host resolver that resolves no name, so such a request fails at once and sends nothing).
Images with loading="lazy" are made eager first, as a reader scrolling down would load them;
folded <details> sections are opened for the checks (and left open for the screenshots with
--open-details).
Then writes a full-page screenshot (at most 16000 px high; the output says when cut) and
one screenshot per --section-screenshot, clipped to the first element the selector matches.
The screenshots are written even when a check fails, to look at what went wrong.

Usage: check_report.py REPORT.html --screenshot OUT.png
           [--section-screenshot CSS_SELECTOR OUT2.png]... [--open-details]
           [--chromium PATH] [--timeout S]
(exit 0 and a JSON summary on stdout: images, svgs, folded_sections, console_errors,
page_height_px, screenshots; exit 1 and one line per problem on stderr)
"""

import argparse
import base64
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import tempfile
import time

try:
    import websocket
except ImportError as e:  # never pass silently without the DevTools client
    sys.exit(
        f"check_report.py: {e}; install tests/browser/requirements.txt "
        "(source scripts/setup.sh puts a virtual environment with it first on PATH)"
    )

VIEWPORT = (1400, 900)
MAX_SHOT_HEIGHT = 16000
LOCAL_SCHEMES = ("file:", "data:", "blob:", "about:")
CHROMIUM_FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--remote-debugging-port=0", "--hide-scrollbars",
    # Resolve no host name: a report that reaches out fails here at once, sending nothing.
    "--host-resolver-rules=MAP * ~NOTFOUND",
]
# Per image and per outermost inline svg, what the checks need; lazy images made eager.
INSPECT_JS = """(async () => {
  // Folded sections (<details>) opened, so that what they hold is laid out and checked;
  // folded again at the end, as the reader finds the page.
  const folded = [...document.querySelectorAll('details:not([open])')];
  for (const d of folded) d.open = true;
  const imgs = [...document.images];
  for (const i of imgs) if (i.loading === 'lazy') i.loading = 'eager';
  await Promise.all(imgs.filter(i => !i.complete).map(i => new Promise(r => {
    i.addEventListener('load', r); i.addEventListener('error', r); setTimeout(r, 5000); })));
  const svgs = [...document.querySelectorAll('svg')].filter(s => !s.parentElement.closest('svg'));
  const found = {
    imgs: imgs.map(i => ({src: i.getAttribute('src') || '', alt: i.alt, complete: i.complete,
                          width: i.naturalWidth})),
    svgs: svgs.map((s, k) => {
      const t = s.querySelector('title');
      const name = s.id ? '#' + s.id : (s.getAttribute('aria-label') || (t && t.textContent) || '');
      let box = {width: 0, height: 0};
      try { box = s.getBBox(); } catch (e) {}
      return {index: k, name: name.trim().slice(0, 80), width: box.width, height: box.height};
    }),
    folded: folded.length,
  };
  if (!OPEN_DETAILS) for (const d of folded) d.open = false;
  return found;
})()"""
# The page rectangle of the first element a selector matches, scrolled into view.
ELEMENT_BOX_JS = """(sel => {
  let e;
  try { e = document.querySelector(sel); } catch (err) { return {error: String(err)}; }
  if (!e) return null;
  e.scrollIntoView({block: 'start'});
  const r = e.getBoundingClientRect();
  return {x: r.left + window.scrollX, y: r.top + window.scrollY, width: r.width, height: r.height};
})"""


class Fatal(Exception):
    """A problem after which the check cannot go on."""


def one_line(text, limit=300):
    text = " | ".join(part.strip() for part in str(text).splitlines() if part.strip())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def short(text, limit=80):
    return text if len(text) <= limit else text[: limit - 3] + "..."


class DevTools:
    """One DevTools websocket: commands answered in order, events kept for later checks."""

    def __init__(self, url):
        # Chromium refuses a websocket handshake with an Origin unless allowed by a flag.
        self.ws = websocket.create_connection(url, timeout=30, suppress_origin=True)
        self.last_id = 0
        self.events = []

    def _receive(self, deadline, what):
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise Fatal(f"timed out waiting for {what}")
        self.ws.settimeout(remaining)
        try:
            message = json.loads(self.ws.recv())
        except websocket.WebSocketTimeoutException:
            raise Fatal(f"timed out waiting for {what}") from None
        except websocket.WebSocketConnectionClosedException:
            raise Fatal(f"Chromium closed the DevTools connection waiting for {what}") from None
        if "method" in message:
            self.events.append(message)
        return message

    def call(self, method, timeout=30, **params):
        self.last_id += 1
        self.ws.send(json.dumps({"id": self.last_id, "method": method, "params": params}))
        deadline = time.monotonic() + timeout
        while True:
            message = self._receive(deadline, method)
            if message.get("id") == self.last_id:
                if "error" in message:
                    raise Fatal(f"{method}: {message['error'].get('message')}")
                return message.get("result", {})

    def wait_event(self, method, timeout):
        if any(e["method"] == method for e in self.events):
            return
        deadline = time.monotonic() + timeout
        while self._receive(deadline, f"{method} ({timeout:g} s)").get("method") != method:
            pass

    def evaluate(self, expression, timeout=30):
        result = self.call("Runtime.evaluate", timeout=timeout, expression=expression,
                           returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in result:
            raise Fatal(f"evaluating the checks failed: {one_line(result['exceptionDetails'])}")
        return result["result"].get("value")

    def close(self):
        self.ws.close()


class ChromiumFailed(Fatal):
    def __init__(self, process, message):
        super().__init__(message)
        self.process = process


def start_chromium(chromium, profile, log):
    """Chromium in its own process group, and the port of its DevTools endpoint."""
    process = subprocess.Popen(
        [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "about:blank"],
        stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True,
    )
    port_file = profile / "DevToolsActivePort"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        if process.poll() is not None:
            break
        lines = port_file.read_text().splitlines() if port_file.exists() else []
        if len(lines) >= 2:
            return process, int(lines[0])
        time.sleep(0.1)
    log.flush()
    tail = one_line(pathlib.Path(log.name).read_text(errors="replace")[-600:])
    state = f"exited with {process.returncode}" if process.poll() is not None else "gave no port"
    raise ChromiumFailed(process, f"Chromium {state} within 30 s: {tail}")


def stop_chromium(process):
    """Ends the process group we started (browser, zygotes, renderers) and reaps it."""
    for sig, wait in ((signal.SIGTERM, 5), (signal.SIGKILL, 5)):
        if process.poll() is not None:
            break
        try:
            os.killpg(process.pid, sig)
            process.wait(wait)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            pass
    try:  # children left after the browser itself exited
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def page_problems(events):
    """One line per exception, console error, error log entry and outside request."""
    problems = []
    for event in events:
        method, p = event["method"], event.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = p["exceptionDetails"]
            text = d.get("exception", {}).get("description") or d.get("text", "")
            where = f"{d.get('url', '')}:{d.get('lineNumber', 0) + 1}"
            problems.append(f"uncaught exception at {short(where)}: {one_line(text)}")
        elif method == "Runtime.consoleAPICalled" and p["type"] in ("error", "assert"):
            args = [a.get("value", a.get("description", a.get("type"))) for a in p["args"]]
            problems.append(f"console.{p['type']}: {one_line(' '.join(map(str, args)))}")
        elif method == "Log.entryAdded" and p["entry"]["level"] == "error":
            e = p["entry"]
            url = f" ({short(e['url'])})" if e.get("url") else ""
            problems.append(f"browser log error{url}: {one_line(e['text'])}")
        elif method == "Network.requestWillBeSent":
            url = p["request"]["url"]
            if not url.startswith(LOCAL_SCHEMES):
                problems.append(f"request outside the report: {short(url)} (must be self-contained)")
    return list(dict.fromkeys(problems))


def screenshot(tools, clip, out):
    shot = tools.call("Page.captureScreenshot", timeout=120, format="png",
                      captureBeyondViewport=True, clip={**clip, "scale": 1})
    out = pathlib.Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(base64.b64decode(shot["data"]))
    return str(out)


def check(browser, port, report, args):
    """Loads the report and checks it; returns the summary and the problems."""
    target = browser.call("Target.createTarget", url="about:blank")["targetId"]
    page = DevTools(f"ws://127.0.0.1:{port}/devtools/page/{target}")
    try:
        for domain in ("Runtime", "Log", "Page", "Network"):
            page.call(f"{domain}.enable")
        page.call("Emulation.setDeviceMetricsOverride", width=VIEWPORT[0], height=VIEWPORT[1],
                  deviceScaleFactor=1, mobile=False)
        page.events.clear()  # about:blank's own
        navigation = page.call("Page.navigate", url=report.as_uri())
        if navigation.get("errorText"):
            raise Fatal(f"cannot open {report}: {navigation['errorText']}")
        page.wait_event("Page.loadEventFired", args.timeout)
        found = page.evaluate(INSPECT_JS.replace("OPEN_DETAILS", json.dumps(args.open_details)),
                              timeout=args.timeout)
        problems = []
        for img in found["imgs"]:
            if not img["complete"] or img["width"] == 0:
                state = "did not finish loading" if not img["complete"] else "is broken"
                problems.append(f"<img src={short(img['src'])!r} alt={img['alt']!r}> {state}")
        for svg in found["svgs"]:
            if svg["width"] == 0 or svg["height"] == 0:
                problems.append(f"inline <svg> #{svg['index']} {svg['name']!r} has an empty "
                                f"bounding box ({svg['width']} x {svg['height']})")

        metrics = page.call("Page.getLayoutMetrics")
        size = metrics.get("cssContentSize") or metrics["contentSize"]
        width, height = int(size["width"]), int(size["height"])
        shots = [screenshot(page, {"x": 0, "y": 0, "width": width,
                                   "height": min(height, MAX_SHOT_HEIGHT)}, args.screenshot)]
        if height > MAX_SHOT_HEIGHT:
            print(f"check_report.py: page is {height} px high; {args.screenshot} shows the first "
                  f"{MAX_SHOT_HEIGHT} px", file=sys.stderr)
        for selector, out in args.section_screenshot:
            box = page.evaluate(f"{ELEMENT_BOX_JS}({json.dumps(selector)})")
            if box is None or "error" in box:
                problems.append(f"--section-screenshot {selector!r}: "
                                + (one_line(box["error"]) if box else "matches no element"))
            elif box["width"] < 1 or box["height"] < 1:
                problems.append(f"--section-screenshot {selector!r}: the element has no size")
            else:
                shots.append(screenshot(page, box, out))
        page.evaluate("new Promise(r => setTimeout(r, 100))")  # collect late events
        problems = page_problems(page.events) + problems
        summary = {
            "images": len(found["imgs"]),
            "svgs": len(found["svgs"]),
            "folded_sections": found["folded"],
            "console_errors": sum(
                e["method"] == "Runtime.consoleAPICalled"
                and e["params"]["type"] in ("error", "assert") for e in page.events),
            "page_height_px": height,
            "screenshot_capped_px": MAX_SHOT_HEIGHT if height > MAX_SHOT_HEIGHT else None,
            "screenshots": shots,
        }
        return summary, problems
    finally:
        page.close()


def main():
    parser = argparse.ArgumentParser(description="Browser check of a self-contained HTML report.")
    parser.add_argument("report", type=pathlib.Path)
    parser.add_argument("--screenshot", required=True, metavar="OUT.png")
    parser.add_argument("--section-screenshot", nargs=2, action="append", default=[],
                        metavar=("CSS_SELECTOR", "OUT.png"))
    parser.add_argument("--open-details", action="store_true",
                        help="leave every folded <details> section open for the screenshots")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--timeout", type=float, default=60, help="seconds for the page to load")
    args = parser.parse_args()
    report = args.report.resolve()
    if not report.is_file():
        sys.exit(f"check_report.py: no such file: {args.report}")
    if not (shutil.which(args.chromium) and os.access(shutil.which(args.chromium), os.X_OK)):
        sys.exit(f"check_report.py: no Chromium at {args.chromium} "
                 "(Debian's chromium package: source scripts/setup.sh)")
    # A killed check still ends Chromium and removes its profile (the finally below).
    signal.signal(signal.SIGTERM, lambda *_: sys.exit("check_report.py: terminated"))

    scratch = pathlib.Path(tempfile.mkdtemp(prefix="check_report."))
    process = None
    try:
        profile = scratch / "profile"
        profile.mkdir()
        with open(scratch / "chromium.log", "w+") as log:
            try:
                process, port = start_chromium(args.chromium, profile, log)
            except ChromiumFailed as e:
                process = e.process
                raise
            browser_url = "ws://127.0.0.1:{}{}".format(
                port, (profile / "DevToolsActivePort").read_text().splitlines()[1])
            browser = DevTools(browser_url)
            try:
                summary, problems = check(browser, port, report, args)
            finally:
                browser.close()
    except (Fatal, OSError, websocket.WebSocketException) as e:
        sys.exit(f"check_report.py: {one_line(e)}")
    finally:
        if process is not None:
            stop_chromium(process)
        shutil.rmtree(scratch, ignore_errors=True)
    if problems:
        for problem in problems:
            print(f"check_report.py: {problem}", file=sys.stderr)
        sys.exit(1)
    json.dump(summary, sys.stdout)
    print()


if __name__ == "__main__":
    main()
