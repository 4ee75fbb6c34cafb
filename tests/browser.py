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




def embedded_figures(text: str) -> list[tuple[str, bytes]]:
    """``(file name, bytes)`` of every embedded figure of a report, in page order (the name is
    the ``figures/<name>`` its caption gives)."""
    import base64

    found = re.findall(r'<img src="data:image/(?:png|jpeg);base64,([^"]+)"[^>]*>'
                       r'<figcaption>.*?figures/([^<]+)</code>', text)
    return [(name, base64.b64decode(data)) for data, name in found]


def plain_cells(text: str) -> str:
    """The page without the cells' ``data-label`` attributes (the phone layout's column names),
    so that tests can look for ``<td>value</td>``."""
    return re.sub(r' data-label="[^"]*"', "", text)


#: Layout numbers of the page once loaded, posted to the page that frames it (test copy only).
_LAYOUT = ("<script>addEventListener('load',function(){var d=document.documentElement;"
           "var r={inner:window.innerWidth,scroll:d.scrollWidth,images:[],tables:[],rig:null};"
           "var ims=document.images;for(var i=0;i<ims.length;i++){var b=ims[i]"
           ".getBoundingClientRect();r.images.push([b.width,b.top+window.scrollY,"
           "ims[i].naturalWidth,ims[i].closest('section')?ims[i].closest('section').id:'']);}"
           "var ts=document.querySelectorAll('table');for(var i=0;i<ts.length;i++){var b=ts[i]"
           ".getBoundingClientRect();r.tables.push([b.width,b.top+window.scrollY]);}"
           "r.main=document.querySelector('main').getBoundingClientRect().width;"
           "parent.postMessage(JSON.stringify(r),'*');});</script>")

#: The page that frames the report at a given width (a headless window is at least 500 px
#: wide, so a phone's 390 px is a frame of that width) and writes what the report posts.
_FRAME = ("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><style>body{{margin:0}}"
          "iframe{{border:0;display:block;width:{w}px;height:{h}px}}</style></head><body>"
          "<iframe src=\"{src}\"></iframe><script>addEventListener('message',function(e){{"
          "var p=document.createElement('pre');p.id='layout';p.textContent=e.data;"
          "document.body.appendChild(p);}});</script></body></html>")


def framed(report, width: int, height: int, *, probe: bool = False):
    """A page showing a copy of ``report`` in a frame ``width`` x ``height`` CSS pixels (with
    :data:`_LAYOUT` in the copy when ``probe``)."""
    text = report.read_text()
    if probe:
        text = text.replace("default-src 'none';",
                            "default-src 'none'; script-src 'unsafe-inline';")
        text = text.replace("</body>", _LAYOUT + "</body>")
    inner = report.with_name(f"framed_{width}{'_probe' if probe else ''}.html")
    inner.write_text(text)
    page = report.with_name(f"frame_{width}{'_probe' if probe else ''}.html")
    page.write_text(_FRAME.format(w=width, h=height, src=inner.name))
    return page


def layout(report, tmp_path, width: int, height: int = 900) -> tuple[dict, list[str]]:
    """Widths and places of the images and tables of ``report`` shown ``width`` CSS pixels
    wide: ``inner`` (the report's window width), ``scroll`` (its scroll width), ``main`` (the
    content's width), ``images`` as [shown width, top, natural width, section id],
    ``tables`` as [width, top]."""
    page = framed(report, width, height, probe=True)
    dom, console = chromium(page, tmp_path, "--dump-dom", "--window-size=1400,1000",
                            "--virtual-time-budget=10000")
    found = re.search(r'<pre id="layout">(.*?)</pre>', dom)
    assert found, dom[-500:]
    return json.loads(html.unescape(found.group(1))), console


def screenshot_at(report, shot, tmp_path, width: int, height: int) -> list[str]:
    """A screenshot of ``report`` shown ``width`` x ``height`` CSS pixels (framed, the
    window cropped to it) into ``shot``; console lines."""
    from PIL import Image

    page = framed(report, width, height)
    _, console = chromium(page, tmp_path, f"--screenshot={shot}",
                          f"--window-size={max(width, 500)},{height}",
                          "--virtual-time-budget=10000")
    with Image.open(shot) as im:
        im.crop((0, 0, width, height)).save(shot)
    return console
