"""Headless Debian chromium on a page: DOM, console messages and screenshots (report tests)."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="Debian's chromium is not on PATH (.ci/run installs it with "
                             "apt-get install chromium)")

#: Writes every image's natural size into the DOM once the page has loaded (test copy only).
_PROBE = ("<script>addEventListener('load',function(){var r=[];for(var i=0;i<document.images"
          ".length;i++){var m=document.images[i];r.push([m.naturalWidth,m.naturalHeight,"
          "m.complete]);}var p=document.createElement('pre');p.id='probe';p.textContent="
          "JSON.stringify(r);document.body.appendChild(p);});</script>")


def chromium(page, tmp_path, *flags):
    """Run headless chromium on a file; returns (stdout, console lines from stderr)."""
    profile = tmp_path / f"profile-{len(list(tmp_path.iterdir()))}"
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--no-first-run", f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0",
           "--hide-scrollbars", *flags, page.as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr[-2000:]
    # chromium logs every console message (errors, warnings, CSP violations, uncaught
    # exceptions) of the page as "...:CONSOLE..." lines on stderr
    console = [ln for ln in proc.stderr.splitlines() if ":CONSOLE" in ln]
    return proc.stdout, console


def probe(report, tmp_path):
    """Natural sizes of the images of a copy of ``report`` with :data:`_PROBE` added."""
    text = report.read_text()
    text = text.replace("default-src 'none';", "default-src 'none'; script-src 'unsafe-inline';")
    probe_page = report.with_name("probe.html")
    probe_page.write_text(text.replace("</body>", _PROBE + "</body>"))
    dom, console = chromium(probe_page, tmp_path, "--dump-dom")
    found = re.search(r'<pre id="probe">(.*?)</pre>', dom)
    assert found, dom[-500:]
    return json.loads(html.unescape(found.group(1))), console


def screenshot(page, tmp_path):
    from PIL import Image

    shot = tmp_path / "shot.png"
    _, console = chromium(page, tmp_path, f"--screenshot={shot}", "--window-size=1200,3200")
    rgb = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
    return rgb, console


