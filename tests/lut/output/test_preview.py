"""The 3D preview page (``lut.output.preview``): self-contained, small enough, and it really plays in a browser.

The browser test opens the page in headless Chromium (Debian package ``chromium``; ``scripts/ensure-chromium``
installs it when missing and we are root with apt) at two times via ``preview.html?t=…`` and checks that
both screenshots show a scene and that the 3D scene moved between them.
"""

from __future__ import annotations

import re
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lut.output.plan_file import PlanFileError, load_plan
from lut.output.preview import MAX_FRAMES, frame_indices, preview_data, write_preview

DATA = Path(__file__).resolve().parents[2] / "data"
ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = Path("/usr/bin/chromium")
WINDOW = (1200, 800)
SCENE_TOP_PX = 70  # below the control bar and the info line: only the 3D scene


@pytest.fixture(scope="module", params=("plan_I", "plan_II"))
def plan(request) -> dict:
    return load_plan(DATA / f"{request.param}.json.gz")


class _ResourceFinder(HTMLParser):
    """Every URL a tag would load (src, href, data, srcset, poster) and the text of <style> elements."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[tuple[str, str]] = []
        self.tags: list[str] = []
        self.styles: list[str] = []
        self._in_style = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        self._in_style = tag == "style"
        for name, value in attrs:
            if name in ("src", "href", "data", "srcset", "poster", "action") and value:
                self.urls.append((tag, value))

    def handle_endtag(self, tag: str) -> None:
        self._in_style = False

    def handle_data(self, data: str) -> None:
        if self._in_style:
            self.styles.append(data)


def test_preview_is_self_contained(plan, tmp_path):
    out = write_preview(plan, tmp_path / "preview.html")
    text = out.read_text(encoding="utf-8")
    finder = _ResourceFinder()
    finder.feed(text)
    assert finder.urls == [], f"the page loads resources: {finder.urls}"
    assert finder.tags.count("script") == 2  # the plotly.js bundle and our player, both inline
    assert not any("url(" in s or "@import" in s for s in finder.styles)
    assert "Plotly.newPlot" in text and "lutgenPreview" in text
    assert out.stat().st_size < 6_000_000  # the plotly.js bundle is ~4.8 MB; the plan adds a few hundred kB


def test_preview_data_frames_and_geometry(plan):
    fig, data, note = preview_data(plan)
    frames = data["frames"]
    t = np.asarray(plan["samples"]["t"])
    assert len(frames["t"]) <= MAX_FRAMES and frames["t"][0] == pytest.approx(t[0], abs=1e-4)
    assert frames["t"][-1] == pytest.approx(t[-1], abs=1e-4)
    assert note == ""  # the test plans carry target.shapes
    names = [trace.name for trace in fig.data]
    assert {"chaser base", "arm", "target", "target handle", "joints", "closest pair"} <= set(names)
    n_bodies = data["n_bodies"]
    assert n_bodies == 9  # base + 7 links + target
    assert all(len(p) == 12 * n_bodies for p in frames["poses"])
    # the gripper's grasp frame (last skeleton point) is where the export says, within rounding
    k = len(frames["t"]) - 1
    assert np.allclose(frames["ee"][k], plan["samples"]["ee_position"][-1], atol=1e-3)
    assert len(frames["min_distance_m"]) == len(frames["closest_pair"]) == len(frames["t"])


def test_preview_falls_back_without_target_shapes(tmp_path):
    doc = load_plan(DATA / "plan_II.json.gz")
    doc["target"].pop("shapes")
    for key in ("min_distance_m", "closest_pair", "closest_points_m"):
        doc["samples"].pop(key)
    fig, data, note = preview_data(doc, max_frames=10)
    assert "inertia-equivalent box" in note and data["frames"]["min_distance_m"] is None
    assert "target (stand-in box)" in [trace.name for trace in fig.data]
    assert "closest pair" not in [trace.name for trace in fig.data]


def test_preview_needs_the_robot_urdf():
    doc = load_plan(DATA / "plan_II.json.gz")
    doc["robot_urdf"] = "gone/chaser.urdf"
    with pytest.raises(PlanFileError, match="robot_urdf: 'gone/chaser.urdf' not found"):
        preview_data(doc)


def test_frame_indices_keep_both_ends():
    t = np.arange(3001) * 0.02
    idx = frame_indices(t, 300)
    assert len(idx) <= 300 and idx[0] == 0 and idx[-1] == 3000 and np.all(np.diff(idx) > 0)
    assert frame_indices(t[:50], 300).tolist() == list(range(50))


# ---- in a real browser ---------------------------------------------------------------------------


def _chromium() -> Path:
    """Headless Chromium, installed by scripts/ensure-chromium when missing; skip only where it cannot be."""
    if not CHROMIUM.is_file():
        res = subprocess.run([str(ROOT / "scripts" / "ensure-chromium")], capture_output=True, text=True,
                             timeout=900)
        if res.returncode != 0 or not CHROMIUM.is_file():
            pytest.skip(f"headless Chromium unavailable: {res.stderr.strip().splitlines()[-1:] or res.returncode}")
    return CHROMIUM


def _chromium_run(chromium: Path, profile: Path, *args: str) -> subprocess.CompletedProcess:
    """Headless, offline-minded flags; a fresh profile; virtual time lets the page's timers and frames run."""
    cmd = [str(chromium), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={profile}", f"--window-size={WINDOW[0]},{WINDOW[1]}", "--hide-scrollbars",
           "--virtual-time-budget=15000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180)


def _screenshot(chromium: Path, url: str, out: Path, profile: Path) -> np.ndarray:
    res = _chromium_run(chromium, profile, f"--screenshot={out}", url)
    assert out.is_file(), f"no screenshot: {res.stderr[-2000:]}"
    with Image.open(out) as img:
        return np.asarray(img.convert("RGB"), dtype=float)


def test_preview_plays_in_headless_chromium(tmp_path):
    chromium = _chromium()
    doc = load_plan(DATA / "plan_II.json.gz")
    page = write_preview(doc, tmp_path / "preview.html")
    t0, t1 = doc["phases"]["approach"][0], doc["phases"]["stabilization"][1]
    shots = [_screenshot(chromium, f"{page.as_uri()}?t={t:.2f}", tmp_path / f"shot{i}.png", tmp_path / f"profile{i}")
             for i, t in enumerate((t0, t1))]
    scenes = [s[SCENE_TOP_PX:] for s in shots]
    for scene in scenes:
        assert scene.std() > 15, "blank scene: WebGL or the page script failed"
        # the chaser base's gold is on screen: the meshes were drawn, not just the axes
        gold = (np.abs(scene[..., 0] - 0xC9) < 60) & (np.abs(scene[..., 1] - 0xA3) < 60) & (scene[..., 2] < 110)
        assert gold.mean() > 0.002, f"no chaser base in the screenshot ({gold.mean():.4f} of the pixels)"
    moved = np.abs(scenes[0] - scenes[1]).max(axis=2) > 30
    assert moved.mean() > 0.005, f"the scene did not move between t = {t0:.1f} s and {t1:.1f} s"
    # play=1: the player advances by itself (the frame index is mirrored in <body data-frame>)
    dom = _chromium_run(chromium, tmp_path / "profile_play", "--dump-dom", f"{page.as_uri()}?t={t0:.2f}&play=1")
    frame = re.search(r'<body data-frame="(\d+)"', dom.stdout)
    assert frame is not None and int(frame.group(1)) > 10, dom.stdout[:300]
