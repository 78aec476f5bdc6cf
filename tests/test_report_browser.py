"""The HTML report renders in a real browser (headless Chromium, no network).

Chromium comes from the Debian packages; the fixture installs it when it is missing (as root,
with apt-get) and skips with the reason when that is impossible.
"""

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from campaign import run
from campaign.report import build_report
from reports.html import count_figures

from test_report import small

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="session")
def chromium():
    if CHROMIUM.exists():
        return CHROMIUM
    if not shutil.which("apt-get"):
        pytest.skip("chromium is not installed and apt-get is not available to install it")
    if hasattr(os, "geteuid") and os.geteuid() != 0:
        pytest.skip("chromium is not installed and installing it with apt-get needs root")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    try:
        for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "chromium"]):
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=env)
            if done.returncode != 0:
                pytest.skip(f"could not install chromium ({' '.join(cmd)} failed: "
                            f"{done.stderr.strip()[-300:]})")
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"could not install chromium: {exc}")
    if not CHROMIUM.exists():
        pytest.skip("apt-get installed chromium but /usr/bin/chromium is missing")
    return CHROMIUM


@pytest.fixture(scope="module")
def page_path(tmp_path_factory):
    out = tmp_path_factory.mktemp("browser") / "campaign"
    run(small(), out, jobs=1, progress=False)
    return build_report(out, jobs=1, log=lambda _: None)


def _chromium(binary, profile, *args, timeout=120):
    return subprocess.run([str(binary), *FLAGS, f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=timeout)


def test_report_dom_has_the_verdict_table_and_every_figure(chromium, page_path, tmp_path):
    done = _chromium(chromium, tmp_path / "profile", "--dump-dom", page_path.as_uri())
    assert done.returncode == 0, done.stderr[-2000:]
    dom = done.stdout
    assert re.search(r'<section id="verdict">.*?<table class="verdict faults">', dom, re.S)
    assert "position-monitor" in dom and "Fault scenario" in dom
    html = page_path.read_text()
    assert count_figures(dom) == count_figures(html) == 15
    # every image is an embedded PNG (data URI), nothing to fetch
    srcs = re.findall(r'<img [^>]*src="([^"]{0,30})', dom)
    assert len(srcs) == 15 and all(s.startswith("data:image/png;base64,") for s in srcs)


def test_report_screenshot_shows_a_rendered_page(chromium, page_path, tmp_path):
    shot = tmp_path / "report.png"
    done = _chromium(chromium, tmp_path / "profile", f"--screenshot={shot}",
                     "--window-size=1400,3000", page_path.as_uri())
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)
    assert img.shape[:2] == (3000, 1400)
    # a blank or unstyled page is almost uniform; the rendered report has text, tables,
    # the green/red verdict badges and figures: many distinct colours and dark pixels
    rgb = (img[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    assert len(np.unique(rgb, axis=0)) > 500
    assert np.mean(rgb.mean(axis=1) < 128) > 0.005
