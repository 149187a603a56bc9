"""What people look at: ``report.html`` of the demo opened in headless Chromium (no
JavaScript errors, the 3-D views drawn, the summary equal to ``report.json``), the
demo's ``map.bt`` read by OctoMap, and ``align --plot`` / ``--html`` on real data.

The browser is Debian's ``chromium`` (``.ci/run`` installs it); the browser tests skip
with the reason only where none can be found.
"""

from __future__ import annotations

import base64
import json
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import matplotlib.image
import numpy as np
import octomap
import pytest
from cdp import Browser, find_browser, page_url
from conftest import data_path

import slam2world as s2w
from slam2world._slam2world import run_cli

MAX_DEMO_HTML = 15 * 1024 * 1024


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper-size demo's outputs (no figures: those are test_plot's)."""
    d = tmp_path_factory.mktemp("demo")
    assert run_cli(["slam2world", "demo", "-o", str(d), "--no-plots"]) == 0
    return d


@pytest.fixture(scope="module")
def browser() -> Any:
    exe = find_browser()
    if exe is None:
        pytest.skip("no Chromium on PATH (apt-get install chromium; .ci/run installs it)")
    with Browser(exe) as b:
        yield b


def lookup(doc: Any, key: str) -> Any:
    """The value at a dotted JSON path (`fit.intervals.scale.0`)."""
    for part in key.split("."):
        doc = doc[int(part)] if isinstance(doc, list) else doc[part]
    return doc


class _Numbers(HTMLParser):
    """Every element with ``data-key``: (doc, key, data-value, data-len, text)."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[Any]] = []
        self._open: list[Any] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if "data-key" in a:
            self._open = [a.get("data-doc"), a["data-key"], a.get("data-value"), a.get("data-len")]
            self._open.append("")

    def handle_data(self, data: str) -> None:
        if self._open is not None:
            self._open[4] += data

    def handle_endtag(self, tag: str) -> None:
        if self._open is not None and tag == "span":
            self.rows.append(self._open)
            self._open = None


def half_ulp(text: str) -> float:
    """Half a unit in the last digit shown (`0.0123` → 5e-5, `1.50e-9` → 5e-12)."""
    mantissa, _, exp = text.partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (int(exp or 0) - decimals)


def check_numbers(rows: list[list[Any]], docs: dict[str, Any]) -> int:
    """Each number on the page equals its document's: the exact value, and the text shown
    to the reader within its rounding. Returns how many were checked."""
    for doc, key, value, length, text in rows:
        want = lookup(docs[doc], key)
        if length is not None:
            assert int(length) == len(want) == int(text), (doc, key)
            continue
        if want is None:
            assert value == "null" and text == "—", (doc, key, value, text)
            continue
        assert float(value) == float(want), (doc, key, value, want)
        # What the reader sees is the number rounded to the digits shown.
        assert abs(float(text) - float(want)) <= half_ulp(text) * (1 + 1e-9), (doc, key, text, want)
    return len(rows)


def pixel_std(png: bytes, tmp: Path) -> float:
    tmp.write_bytes(png)
    img = matplotlib.image.imread(tmp)
    return float(img[..., :3].std())


@pytest.mark.slow
def test_demo_writes_the_octree_and_the_page(demo: Path) -> None:
    report = json.loads((demo / "report.json").read_text())
    assert report["octree"]["resolution"] == 0.1
    html = (demo / "report.html").read_text()
    assert 1_000_000 < len(html.encode()) <= MAX_DEMO_HTML, len(html.encode())
    # Self-contained: nothing fetched from elsewhere.
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", html)
    assert "url(http" not in html and "@import" not in html
    data = json.loads(
        re.search(r'<script id="s2w-data" type="application/json">(.*?)</script>', html, re.S)[1]
    )
    figures = data["figures"]
    assert figures["cloud"]["n"] <= 300_000 < figures["cloud"]["n_total"]
    assert figures["cloud"]["n"] == -(-figures["cloud"]["n_total"] // figures["cloud"]["stride"])
    assert figures["voxels"]["n_total"] == report["octree"]["leaves_occupied"]
    assert len(figures["pairs"]["error"]) == len(report["pairs"])
    assert figures["pairs"]["error"] == [p["error"] for p in report["pairs"]]
    assert len(figures["scale_factors"]) == len(report["pairs"]) - 1
    # The embedded report is report.json, number for number.
    assert data["report"] == report


@pytest.mark.slow
def test_demo_map_bt_reads_in_octomap_with_the_same_leaves(demo: Path) -> None:
    report = json.loads((demo / "report.json").read_text())
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(demo / "map.bt").encode())
    assert tree.getResolution() == pytest.approx(0.1)
    # The .bt file keeps the max-likelihood state only, so its tree is pruned further than
    # the map in memory: OctoMap and our reader see the same leaves in it...
    ours = s2w.read_bt(demo / "map.bt")
    assert tree.getNumLeafNodes() == ours.num_leaf_nodes
    occupied = [leaf.getSize() for leaf in tree.begin_leafs() if tree.isNodeOccupied(leaf)]
    # ...and the same occupied volume as the demo's octree (the page's voxels, all drawn).
    voxels = json.loads(
        re.search(
            r'<script id="s2w-data" type="application/json">(.*?)</script>',
            (demo / "report.html").read_text(),
            re.S,
        )[1]
    )["figures"]["voxels"]
    assert voxels["n"] == voxels["n_total"] == report["octree"]["leaves_occupied"] > 1000
    sizes = np.frombuffer(base64.b64decode(voxels["size"]), dtype="<f4")
    n_fine = int(np.round((sizes / 0.1) ** 3).sum())
    assert sum(round((e / 0.1) ** 3) for e in occupied) == n_fine == len(ours.occupied_centers())


@pytest.mark.slow
def test_summary_numbers_equal_the_reports_without_a_browser(demo: Path) -> None:
    parser = _Numbers()
    parser.feed((demo / "report.html").read_text())
    docs = {
        "report": json.loads((demo / "report.json").read_text()),
        "demo": json.loads((demo / "demo.json").read_text()),
    }
    keys = {r[1] for r in parser.rows}
    assert {"t_world_slam.scale", "ape.rmse", "pairs_fitted", "octree.leaves_occupied"} <= keys
    assert check_numbers(parser.rows, docs) > 40
    # Gravity in SLAM axes, computed for the page: world -z carried back by R^T.
    html = (demo / "report.html").read_text()
    shown = {
        k: float(v)
        for k, v in re.findall(r'data-derived="(gravity_slam\.\d)" data-value="([^"]+)"', html)
    }
    t = docs["report"]["t_world_slam"]
    rot = np.asarray(t["matrix"])[:3, :3] / t["scale"]
    want = rot.T @ np.array([0.0, 0.0, -1.0])
    got = np.array([shown[f"gravity_slam.{i}"] for i in range(3)])
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.slow
def test_report_page_renders_in_chromium(demo: Path, browser: Browser, tmp_path: Path) -> None:
    browser.open(page_url(demo / "report.html"))
    browser.wait_for("document.body && document.body.dataset.ready !== undefined")
    assert browser.evaluate("document.body.dataset.ready") == "1", browser.evaluate(
        "document.getElementById('s2w-status').textContent"
    )
    assert browser.errors() == []
    # The 3-D views and the plots are drawn: their pixels vary.
    rects = browser.evaluate(
        "JSON.stringify(['paths-view', 'cloud-view', 'pk-plot', 'error-plot', 'hist-plot']"
        ".map(id => { const r = document.getElementById(id).getBoundingClientRect();"
        " return [id, r.left + scrollX, r.top + scrollY, r.width, r.height]; }))"
    )
    for name, x, y, w, h in json.loads(rects):
        assert w > 300 and h > 200, name
        std = pixel_std(browser.screenshot((x, y, w, h)), tmp_path / f"{name}.png")
        assert std > 0.03, f"{name} looks blank (pixel std {std:.4f})"
    # The voxels toggle on and the view redraws with them.
    before = browser.screenshot(tuple(json.loads(rects)[1][1:]))
    browser.evaluate("document.getElementById('show-voxels').click()")
    browser.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    after = browser.screenshot(tuple(json.loads(rects)[1][1:]))
    assert before != after
    assert browser.evaluate("window.s2wCloudView.layers.filter(l => l.kind === 'cubes')[0].visible")
    # What the reader sees equals report.json.
    rows = json.loads(
        browser.evaluate(
            "JSON.stringify(Array.from(document.querySelectorAll('[data-key]')).map(e =>"
            " [e.dataset.doc, e.dataset.key, e.dataset.value ?? null, e.dataset.len ?? null,"
            " e.textContent]))"
        )
    )
    docs = {
        "report": json.loads((demo / "report.json").read_text()),
        "demo": json.loads((demo / "demo.json").read_text()),
    }
    assert check_numbers(rows, docs) > 40
    (tmp_path / "page.png").write_bytes(browser.screenshot())
    assert browser.errors() == []


@pytest.mark.slow
def test_align_plot_on_fr2_desk(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    d = data_path("evo_tum_fr2_desk")
    est, ref = d / "fr2_desk_ORB_kf_mono.txt", d / "fr2_desk_groundtruth.txt"
    save = tmp_path / "fig" / "ape.png"
    save.parent.mkdir()
    page = tmp_path / "align.html"
    args = ["align", str(est), str(ref), "--plot", "--save-plot", str(save), "--html", str(page)]
    capfd.readouterr()
    assert run_cli(["slam2world", *args, "--json"]) == 0
    out, err = capfd.readouterr()
    doc = json.loads(out)
    assert "ape_map.png" in err and "align.html" in err
    for name in ("ape_map.png", "ape_raw.png"):
        path = save.parent / name
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        img = matplotlib.image.imread(path)
        assert img.shape[:2] == (800, 1200), (name, img.shape)
        rgb = (img[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
        assert float(img[..., :3].std()) > 0.05, name
        # Lines, text and a colour ramp: many colours, not a blank or flat image.
        assert len(np.unique(rgb, axis=0)) > 200, name
        # Most of the figure is the white background, but not all of it.
        white = np.all(rgb > 250, axis=1).mean()
        assert 0.4 < white < 0.99, (name, white)
    parser = _Numbers()
    parser.feed(page.read_text())
    assert check_numbers(parser.rows, {"align": doc}) > 20


@pytest.mark.slow
def test_align_html_renders_in_chromium(tmp_path: Path, browser: Browser) -> None:
    d = data_path("evo_tum_fr2_desk")
    page = tmp_path / "align.html"
    args = ["align", str(d / "fr2_desk_ORB_kf_mono.txt"), str(d / "fr2_desk_groundtruth.txt")]
    assert run_cli(["slam2world", *args, "--skip-init", "auto", "--html", str(page)]) == 0
    browser.events.clear()
    browser.open(page_url(page))
    browser.wait_for("document.body && document.body.dataset.ready !== undefined")
    assert browser.evaluate("document.body.dataset.ready") == "1"
    assert browser.errors() == []
    # No cloud in an alignment: its section is hidden, the rest drawn.
    assert (
        browser.evaluate("getComputedStyle(document.getElementById('cloud-section')).display")
        == "none"
    )


def test_align_plot_without_matches_is_an_error(tmp_path: Path) -> None:
    d = data_path("evo_tum_fr2_desk")
    est = tmp_path / "late.txt"
    rows = (d / "fr2_desk_ORB_kf_mono.txt").read_text().splitlines()
    est.write_text(
        "\n".join(
            f"{float(r.split()[0]) + 1e4} " + " ".join(r.split()[1:])
            for r in rows
            if r and not r.startswith("#")
        )
    )
    save = tmp_path / "ape.png"
    args = ["align", str(est), str(d / "fr2_desk_groundtruth.txt"), "--save-plot", str(save)]
    assert run_cli(["slam2world", *args]) == 1
    assert not list(tmp_path.glob("ape_*.png"))


def test_conversion_write_all_writes_the_page(tmp_path: Path) -> None:
    log = tmp_path / "s.mcap"
    assert run_cli(["slam2world", "simulate", "-o", str(log), "--reduced", "8"]) == 0
    conv = s2w.convert(log, octree_resolution=0.2)
    conv.write_all(tmp_path / "out")
    html = (tmp_path / "out" / "report.html").read_text()
    parser = _Numbers()
    parser.feed(html)
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert check_numbers(parser.rows, {"report": report}) > 30


@pytest.mark.slow
def test_rerun_recording_of_a_conversion(tmp_path: Path) -> None:
    from slam2world import rerun as s2w_rerun

    log = tmp_path / "s.mcap"
    assert run_cli(["slam2world", "simulate", "-o", str(log), "--reduced", "8"]) == 0
    out = tmp_path / "out"
    s2w.convert(log, octree_resolution=0.2).write_all(out)
    report = json.loads((out / "report.json").read_text())
    data = s2w_rerun.read_outputs(out)
    # What the recording logs is what the outputs hold.
    assert data["cloud"].shape == (report["points"], 3)
    assert data["pair_error"].tolist() == [p["error"] for p in report["pairs"]]
    assert len(data["voxel_sizes"]) == report["octree"]["leaves_occupied"]
    np.testing.assert_allclose(data["voxel_sizes"], 0.2, rtol=1e-6)
    np.testing.assert_array_equal(data["t_world_slam"], report["t_world_slam"]["matrix"])
    rrd = tmp_path / "world.rrd"
    try:
        import rerun  # type: ignore[import-not-found, unused-ignore]  # noqa: F401
    except ImportError:
        # Without rerun-sdk: a clear message and exit 1, nothing written.
        assert s2w_rerun.main([str(out), "-o", str(rrd)]) == 1
        assert not rrd.exists()
        return
    assert s2w_rerun.main([str(out), "-o", str(rrd)]) == 0
    assert rrd.read_bytes()[:4] == b"RRF2" and rrd.stat().st_size > 20_000


def test_conversion_write_html_keeps_to_its_limits(tmp_path: Path) -> None:
    log = tmp_path / "s.mcap"
    assert run_cli(["slam2world", "simulate", "-o", str(log), "--reduced", "8"]) == 0
    conv = s2w.convert(log, octree_resolution=0.1)
    page = tmp_path / "page.html"
    conv.write_html(page, max_points=1000, max_cubes=50)
    figures = json.loads(
        re.search(
            r'<script id="s2w-data" type="application/json">(.*?)</script>', page.read_text(), re.S
        )[1]
    )["figures"]
    cloud, voxels = figures["cloud"], figures["voxels"]
    assert cloud["n"] <= 1000 < cloud["n_total"]
    assert voxels["n"] <= 50 < voxels["n_total"] and voxels["shown_resolution"] > 0.1
    with pytest.raises(ValueError, match="max_points"):
        conv.write_html(page, max_points=0)


@pytest.mark.slow
def test_a_prior_conversion_page_draws_the_heights_and_the_ground(
    tmp_path: Path, browser: Browser
) -> None:
    log = tmp_path / "g.mcap"
    sets = ["camera_height=1.2", "height_loop=0", "height_slow=0", "look_height=0.6"]
    args = ["simulate", "-o", str(log), "--reduced", "4", "--no-reference", "--no-imu"]
    assert run_cli(["slam2world", *args, *[a for s in sets for a in ("--set", s)]]) == 0
    out = tmp_path / "o"
    assert (
        run_cli(["slam2world", "convert", str(log), "-o", str(out), "-q", "--camera-height", "1.2"])
        == 0
    )
    page = out / "report.html"
    report = json.loads((out / "report.json").read_text())
    # The prior's card: every number equals report.json's.
    parser = _Numbers()
    parser.feed(page.read_text())
    keys = {r[1] for r in parser.rows}
    assert {"prior.scale", "prior.plane.inliers", "prior.height_rms", "prior.scale_sigma"} <= keys
    assert check_numbers(parser.rows, {"report": report}) > 8
    browser.events.clear()
    browser.open(page_url(page))
    browser.wait_for("document.body && document.body.dataset.ready !== undefined")
    assert browser.evaluate("document.body.dataset.ready") == "1", browser.evaluate(
        "document.getElementById('s2w-status').textContent"
    )
    assert browser.errors() == []
    assert "heights" in browser.evaluate("document.getElementById('s2w-status').textContent")
    rect = json.loads(
        browser.evaluate(
            "JSON.stringify((r => [r.left + scrollX, r.top + scrollY, r.width, r.height])"
            "(document.getElementById('heights-plot').getBoundingClientRect()))"
        )
    )
    assert pixel_std(browser.screenshot(tuple(rect)), tmp_path / "heights.png") > 0.03
    # The scale along the run: drawn, its caption counting the report's windows.
    windows = [w for w in report["prior"]["profile"] if w["scale"] is not None]
    assert "profile" in browser.evaluate("document.getElementById('s2w-status').textContent")
    caption = browser.evaluate("document.getElementById('profile-caption').textContent")
    assert caption.startswith(f"{len(windows)} windows of ")
    rect = json.loads(
        browser.evaluate(
            "JSON.stringify((r => [r.left + scrollX, r.top + scrollY, r.width, r.height])"
            "(document.getElementById('profile-plot').getBoundingClientRect()))"
        )
    )
    assert pixel_std(browser.screenshot(tuple(rect)), tmp_path / "profile.png") > 0.03
    # The ground plane is drawn in the 3-D view, and its toggle hides it.
    assert not browser.evaluate("document.getElementById('show-ground').disabled")
    lines = "window.s2wCloudView.layers.filter(l => l.kind === 'line' && l.visible).length"
    shown = browser.evaluate(lines)
    browser.evaluate("document.getElementById('show-ground').click()")
    assert browser.evaluate(lines) == shown - 1
    assert browser.errors() == []
