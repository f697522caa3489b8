"""The HTML report: escaped, self-contained, every image found, and (in a browser) interactive."""

from __future__ import annotations

import math
import os
import re
import time
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest
from PIL import Image

from hzval.io import codecs, documents
from hzval.report import columns as report_columns
from hzval.report import pages as report
from tests.helpers import chromium_page

NASTY_NAME = "<b>x.png"
COMMAND = "hzval sweep '<b>x.png' --azimuths -15:15:15 --out 'a&b' && echo \"<script>alert(1)</script>\""
WEIRD_FOLDER = "frames/az +0 #1"  # a frame folder with a space and a '#'
LEAK_RGB, FALSE_SHADOW_RGB = (255, 127, 14), (31, 119, 180)


# --------------------------------------------------------------------------
# A fake sweep output: PNG previews with some structure, and its metrics
# --------------------------------------------------------------------------


def _bricks(n: int) -> np.ndarray:
    """Height in [0, 1]: a running-bond brick wall with bevelled edges, ``n x n``."""
    r, c = np.mgrid[0:n, 0:n].astype(np.float64)
    bh, bw = max(n // 8, 2), max(n // 4, 4)
    row = np.floor(r / bh)
    cc = (c + (row % 2) * bw / 2) % bw
    rr = r % bh
    edge = np.minimum(np.minimum(rr, bh - 1 - rr), np.minimum(cc, bw - 1 - cc))
    return np.clip(edge / max(bh / 4, 1.0), 0, 1)


def _shadow(h: np.ndarray, az: float, el: float, depth: float, step: float) -> np.ndarray:
    """1 where the light at ``az, el`` (degrees) is visible, marching the height field."""
    n = h.shape[0]
    r, c = np.mgrid[0:n, 0:n].astype(np.float64)
    dx, dy = math.cos(math.radians(az)), -math.sin(math.radians(az))  # +y is up on screen
    tan_e = math.tan(math.radians(el))
    lit = np.ones_like(h, dtype=bool)
    t = step
    while t <= n / 3:
        rs = np.mod(np.rint(r + dy * t), n).astype(int)
        cs = np.mod(np.rint(c + dx * t), n).astype(int)
        lit &= h[rs, cs] * depth <= h * depth + t * tan_e
        t += step
    return lit.astype(np.float64)


def _srgb_u8(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0, 1)
    return codecs.unit_to_u8(np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055))


def fake_frame_images(n: int, az: float, el: float = 30.0) -> dict[str, np.ndarray]:
    """Truth, horizon-mapped, plain, FLIP and visibility-difference previews of one frame."""
    from matplotlib import colormaps

    h = _bricks(n)
    depth = n / 16
    gy, gx = np.gradient(h * depth)
    nrm = np.stack([-gx, gy, np.ones_like(h)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    L = np.array(
        [
            math.cos(math.radians(el)) * math.cos(math.radians(az)),
            math.cos(math.radians(el)) * math.sin(math.radians(az)),
            math.sin(math.radians(el)),
        ]
    )
    albedo = np.where(h > 0.05, 0.65, 0.35)[..., None] * np.array([1.0, 0.62, 0.48])
    ndl = np.clip(nrm @ L, 0, None)[..., None]
    V = _shadow(h, az, el, depth, 0.5)
    F = _shadow(h, az, el + 6.0 + az / 10, depth, 2.0)  # a coarser, biased horizon: leaks
    F = np.minimum(F, _shadow(h, az - 12.0, el, depth, 1.0))  # and some false shadows
    truth, approx, plain = (albedo * (0.08 + 1.4 * ndl * s[..., None]) for s in (V, F, np.ones_like(V)))
    err = np.abs(truth - approx).mean(axis=-1)
    flip = (colormaps["magma"](np.clip(err * 2.5, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)
    vis = np.repeat(codecs.unit_to_u8(0.25 + 0.5 * V)[..., None], 3, axis=-1)
    vis[(F >= 0.5) & (V < 0.5)] = LEAK_RGB
    vis[(F < 0.5) & (V >= 0.5)] = FALSE_SHADOW_RGB
    return {
        "truth_png": _srgb_u8(truth),
        "horizon_png": _srgb_u8(approx),
        "plain_png": _srgb_u8(plain),
        "flip_png": flip,
        "visdiff_png": vis,
        "visibility_png": codecs.unit_to_u8(V),
        "factor_png": codecs.unit_to_u8(F),
    }


def make_fake_out(out: Path, size: int = 16, azimuths=(-15.0, 0.0, 15.0)) -> dict:
    """Write a sweep's previews under ``out`` and return its metrics (docs/ARCHITECTURE.md's structure,
    schema 2: the one technique's scores and files under ``frames[i].techniques.horizon``)."""
    frames = []
    own_keys = {
        "horizon_png": "png",
        "flip_png": "flip_png",
        "visdiff_png": "visdiff_png",
        "factor_png": "factor_png",
    }
    for i, az in enumerate(azimuths):
        folder = WEIRD_FOLDER if az == 0 else f"frames/az{az:+g}"
        imgs = fake_frame_images(size, az)
        rel, own = {}, {}
        for key, img in imgs.items():
            name = key.removesuffix("_png") + ".png"
            codecs.write_png_with_preview(out / folder / name, img)  # as the sweep: previews if large
            (own if key in own_keys else rel)[own_keys.get(key, key)] = f"{folder}/{name}"
        for key in ("truth", "visibility"):
            rel[key] = f"{folder}/{key}.exr"  # not written: the report only links files that exist
        own.update(image=f"{folder}/horizon.exr", factor=f"{folder}/factor.exr")
        frames.append(
            {
                "azimuth_deg": az,
                "elevation_deg": 30.0,
                "truth_s": 0.25 + 0.01 * i,
                "files": rel,
                "techniques": {
                    "horizon": {
                        "visibility_mae": 0.02 + 0.01 * i,
                        "leak_fraction": 0.01 * (i + 1),
                        "false_shadow_fraction": 0.004,
                        "flip_mean": 0.05 + 0.02 * abs(az) / 15,
                        "rmse": 0.01 + 0.001 * i,
                        "psnr_db": None if az == 0 else 38.0 - i,
                        "delta_e2000_mean": 1.2 + 0.3 * i,
                        "seconds": 0.004,
                        "files": own,
                    }
                },
            }
        )
    metrics = {
        "material": {
            "name": NASTY_NAME,
            "source": "a <i>test</i> height map",
            "digest": "sha256:" + "ab12" * 16,
            "rows": size,
            "cols": size,
            "path": "/tmp/<b>x.png",
        },
        "schema_version": 2,
        "parameters": {
            "depth": 0.05,
            "boundary": "wrap",
            "elevation_deg": 30.0,
            "azimuths_deg": list(azimuths),
            "light": "hard",
            "light_radius_deg": 0.0,
            "effects": ["shadow", "diffuse", "interreflection"],
            "spp": 16,
            "seed": 0,
            "supersampling": 1,
        },
        "versions": {
            "hzval": "0.1.0",
            "mitsuba": "3.7.1",
            "drjit": "1.2.0",
            "llvm": "19.1.7",
            "variant": "llvm_ad_rgb",
            "python": "3.11.2",
            "machine": "Linux x86_64, 2 CPUs <cpu>",
        },
        "timings": {
            "bake_s": 0.41,
            "bake_cached": False,
            "truth_setup_s": 0.8,
            "horizon_setup_s": 0.2,
            "truth_s": sum(f["truth_s"] for f in frames),
            "horizon_s": 0.004 * len(frames),
            "compare_s": 0.3,
            "write_s": 0.15,
        },
        "simulated": {"truth": ["shadow", "diffuse", "interreflection"], "horizon": ["shadow", "diffuse"]},
        "techniques": {
            "horizon": {
                "label": "horizon map",
                "file_stem": "horizon",
                "summary": "Lengyel's",
                "parameters": {
                    "k": 8.0,
                    "path": "exact",
                    "ambient": "mean_cos2",
                    "bake_radius": 16,
                    "bake_angles": 32,
                },
                "simulated": ["shadow", "diffuse"],
            }
        },
        "frames": frames,
    }
    documents.write_json(out / "metrics.json", metrics)
    return metrics


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs: list[str] = []
        self.links: list[str] = []
        self.tags: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.imgs.append(a.get("src"))
        elif tag == "a" and a.get("href"):
            self.links.append(a["href"])


def _local(out: Path, url: str) -> Path:
    parts = urlsplit(url)
    assert not parts.scheme and not parts.netloc, url
    return out / unquote(parts.path)


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "out dir"
    metrics = make_fake_out(out)
    index = report.write_report(out, metrics, command=COMMAND)
    return out, index, metrics


# --------------------------------------------------------------------------
# Fast tests
# --------------------------------------------------------------------------


def test_report_is_written_with_its_plots(report_dir):
    out, index, _ = report_dir
    assert index == out / "index.html" and index.is_file()
    for name in ("metrics.png", "timings.png"):
        data = (out / "plots" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", name
    from PIL import Image

    with Image.open(out / "plots" / "metrics.png") as img:
        assert img.width > 600
    assert not [p for p in out.rglob(".*")], "temporary files left behind"


def test_names_and_command_are_escaped(report_dir):
    _, index, _ = report_dir
    html = index.read_text(encoding="utf-8")
    assert "<b>" not in html and "<i>" not in html
    assert "&lt;b&gt;x.png" in html
    assert "<script>alert" not in html
    # the reproduce command, escaped, in a <code> block
    assert re.search(
        r'<code id="command">hzval sweep &#39;&lt;b&gt;x.png&#39; .*--out &#39;a&amp;b&#39;', html
    )
    parser = _Refs()
    parser.feed(html)
    assert "b" not in parser.tags and "i" not in parser.tags


def test_every_image_and_link_resolves(report_dir):
    out, index, _ = report_dir
    parser = _Refs()
    parser.feed(index.read_text(encoding="utf-8"))
    # plots; the first screen's worst frame (truth, technique, difference); per frame: swipe 2, flip 2,
    # plain, FLIP, visdiff
    assert len(parser.imgs) == 2 + 3 + 3 * 7
    for src in parser.imgs:
        assert src and _local(out, src).is_file(), src
    assert any("%20%231/" in s for s in parser.imgs), "the folder with ' ' and '#' must be URL-quoted"
    for href in parser.links:
        if not href.startswith("#"):
            assert _local(out, href).is_file(), href
    ids = set(re.findall(r'id="([^"]+)"', index.read_text(encoding="utf-8")))
    for href in parser.links:
        if href.startswith("#"):
            assert href[1:] in ids, href


def test_header_summary_and_frames(report_dir):
    _, index, metrics = report_dir
    html = index.read_text(encoding="utf-8")
    for text in (
        "3.7.1",
        "1.2.0",
        "19.1.7",
        "llvm_ad_rgb",
        "3.11.2",
        "sha256:ab12ab12ab12",
        "interreflection: not modelled by horizon map",
        "leak (F lit, V shadowed)",
        "false shadow",
        "−15° … +15°, step 15° (3 lights)",
    ):
        assert text in html, text
    for key in metrics["parameters"]:
        assert f">{report_columns.value_text(key, metrics['parameters'][key])}<" in html or key in (
            "depth",
            "supersampling",
            "effects",
        ), key
    # one summary row per frame; the worst of each varying column highlighted
    body = html.split("<tbody>")[1].split("</tbody>")[0]
    assert body.count("<tr>") == 3
    assert body.count("worst") >= 6
    assert "∞" in body  # the infinite PSNR
    assert html.count('class="frame"') == 3


def test_missing_layers_and_files_do_not_break_the_page(tmp_path):
    out = tmp_path / "out"
    metrics = make_fake_out(out, azimuths=(0.0, 30.0))
    for f in metrics["frames"]:
        f["techniques"]["horizon"].update(visibility_mae=None, leak_fraction=None, false_shadow_fraction=None)
        del f["techniques"]["horizon"]["files"]["visdiff_png"]
    metrics["frames"][1]["techniques"]["horizon"]["files"]["flip_png"] = "frames/gone/flip.png"
    metrics["timings"]["total_s"] = 3.5
    metrics.pop("versions")
    index = report.write_report(out, metrics, command="")
    html = index.read_text(encoding="utf-8")
    assert "not rendered" in html and "missing file" in html and "frames/gone/flip.png" in html
    assert "not measured" in html and "(not recorded)" in html
    parser = _Refs()
    parser.feed(html)
    for src in parser.imgs:
        assert _local(out, src).is_file(), src


def test_template_never_marks_data_safe():
    for path in report.TEMPLATES.iterdir():
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"\|\s*safe\b|Markup\(|autoescape\s+false", text), path


# --------------------------------------------------------------------------
# In a real browser (Debian's chromium, driven by Playwright; never downloads one)
# --------------------------------------------------------------------------


@pytest.mark.browser
def test_report_in_a_browser(tmp_path):
    out = tmp_path / "out #1"
    metrics = make_fake_out(out, size=64, azimuths=(-30.0, -15.0, 0.0, 15.0, 30.0))
    index = report.write_report(out, metrics, command=COMMAND)
    problems: list[str] = []
    with chromium_page(problems) as page:
        page.on(
            "console",
            lambda m: (
                problems.append(f"console {m.type}: {m.text}") if m.type in ("error", "warning") else None
            ),
        )
        page.goto(index.as_uri(), wait_until="load")
        shot = os.environ.get("HZVAL_REPORT_SCREENSHOT")  # a path: keep a full-page picture to look at
        if shot:
            page.screenshot(path=shot, full_page=True)

        # every image loaded
        images = page.eval_on_selector_all(
            "img", "els => els.map(e => [e.getAttribute('src'), e.complete, e.naturalWidth])"
        )
        assert len(images) == 2 + 3 + 5 * 7
        assert [i for i in images if not (i[1] and i[2] > 0)] == []

        # the first screen (1400 x 900) shows the worst frame's truth | technique | difference, whole
        page.set_viewport_size({"width": 1400, "height": 900})
        boxes = page.eval_on_selector_all(
            ".first-img img",
            "els => els.map(e => { const r = "
            "e.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; })",
        )
        assert len(boxes) == 3
        assert all(
            0 <= left and right <= 1400 and 0 < top and bottom <= 900 and right - left > 200
            for left, top, right, bottom in boxes
        ), boxes
        page.set_viewport_size({"width": 1440, "height": 900})

        # flip: hover shows the other side, in place and labelled; leaving restores it
        fig = page.locator("#frame-2 .flip[data-own='truth']")
        img, tag, view = fig.locator("img"), fig.locator(".which"), fig.locator(".view")
        truth_src, lead_src = img.get_attribute("data-truth"), img.get_attribute("data-lead")
        assert img.get_attribute("src") == truth_src and tag.inner_text() == "truth"
        view.hover()
        assert img.get_attribute("src") == lead_src
        assert tag.inner_text() == "horizon map" and fig.get_attribute("data-showing") == "lead"
        page.mouse.move(2, 2)
        assert img.get_attribute("src") == truth_src and tag.inner_text() == "truth"
        # click flips (with hover flipping off), and again flips back
        page.locator("#hover-flip").uncheck()
        view.click()
        assert img.get_attribute("src") == lead_src and tag.inner_text() == "horizon map"
        view.click()
        assert img.get_attribute("src") == truth_src
        page.locator("#hover-flip").check()

        # the swipe slider moves the clip of the top image
        swipe = page.locator("#frame-0 .swipe")
        over = swipe.locator("img.over")
        clip = lambda: over.evaluate("e => getComputedStyle(e).clipPath")  # noqa: E731
        before = clip()
        swipe.locator(".swipe-range").focus()
        page.keyboard.press("Home")
        assert clip() != before and "100%" in clip()
        page.keyboard.press("End")
        assert re.search(r"inset\(0(px)? 0(px|%)? 0(px)? 0(px)?\)|inset\(0px\)|inset\(0\)", clip()), clip()

        # zoom: 8 screen pixels per image pixel, nearest-neighbour
        target = page.locator("#frame-1 .flip[data-own='lead'] img")
        w_fit = target.bounding_box()["width"]
        page.locator("button[data-zoom='8']").click()
        w8 = target.bounding_box()["width"]
        assert w8 == pytest.approx(64 * 8, abs=1) and w8 != pytest.approx(w_fit, abs=1)
        assert target.evaluate("e => getComputedStyle(e).imageRendering") == "pixelated"
        # panning one view moves the others to the same place
        v = page.locator("#frame-1 .flip[data-own='lead'] .view")
        box = v.bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] / 2 - 60, box["y"] + box["height"] / 2 - 40, steps=5)
        page.mouse.up()
        scrolls = page.eval_on_selector_all(".view", "els => els.map(e => [e.scrollLeft, e.scrollTop])")
        assert scrolls[0][0] > 0 and all(s == pytest.approx(scrolls[0], abs=2) for s in scrolls), scrolls
        page.keyboard.press("0")
        assert target.bounding_box()["width"] == pytest.approx(w_fit, abs=1)

        page.locator("#copy").click()
        page.wait_for_timeout(100)
    assert problems == []


def test_large_images_get_previews_that_average_their_pixels(tmp_path):
    small = np.full((8, 8, 3), 7, np.uint8)
    assert not codecs.write_png_with_preview(tmp_path / "small.png", small)
    assert not (tmp_path / "previews").exists()
    rng = np.random.default_rng(2)
    big = rng.integers(0, 256, (codecs.PREVIEW_ABOVE_PX + 5, 30, 3), dtype=np.uint8)  # 2053 x 30
    assert codecs.write_png_with_preview(tmp_path / "big.png", big)
    with Image.open(tmp_path / codecs.preview_of("big.png")) as im:
        prev = np.asarray(im.convert("RGB"))
    f = 3  # the smallest whole factor down to 1024 rows
    assert prev.shape == (-(-big.shape[0] // f), -(-30 // f), 3)
    block = big[3 * 5 : 3 * 6, 3 * 2 : 3 * 3].astype(np.float64).mean(axis=(0, 1))
    assert np.array_equal(prev[5, 2], np.rint(block).astype(np.uint8))
    left = big.shape[0] % f  # 2053 = 3 x 684 + 1: the last row, repeated
    last = big[-left:, :3].astype(np.float64)
    last = np.concatenate([last] + [last[-1:]] * (f - left))
    assert np.array_equal(prev[-1, 0], np.rint(last.mean(axis=(0, 1))).astype(np.uint8))
    assert codecs.preview_of("frames/az+0/truth.png") == "frames/az+0/previews/truth.png"


@pytest.mark.browser
@pytest.mark.slow(
    reason="a browser on a report of large images; test_report_in_a_browser keeps the browser fast"
)
def test_a_large_report_shows_previews_and_loads_full_images_on_zoom(tmp_path):
    """Images above codecs.PREVIEW_ABOVE_PX are shown by their previews; zooming in loads the full
    files of the views on screen, scaled by the full width; the page's load time is printed."""
    n = codecs.PREVIEW_ABOVE_PX + 52  # 2100: previews of 1050
    out = tmp_path / "big"
    metrics = make_fake_out(out, size=16, azimuths=(-15.0, 15.0))
    metrics["material"].update(rows=n, cols=n)
    for f in metrics["frames"]:  # each small PNG blown up to n x n, nearest
        for _key, rel in (*f["files"].items(), *f["techniques"]["horizon"]["files"].items()):
            if rel.endswith(".png"):
                with Image.open(out / rel) as im:
                    small = np.asarray(im)
                big = np.repeat(np.repeat(small, -(-n // 16), axis=0), -(-n // 16), axis=1)[:n, :n]
                codecs.write_png_with_preview(out / rel, np.ascontiguousarray(big), compress_level=1)
    index = report.write_report(out, metrics, command=COMMAND)
    problems: list[str] = []
    with chromium_page(problems) as page:
        t0 = time.perf_counter()
        page.goto(index.as_uri(), wait_until="load")
        print(f"report of {n} x {n} images loaded in {time.perf_counter() - t0:.2f} s")
        target = page.locator("#frame-0 .flip[data-own='lead'] img")
        assert "/previews/" in target.get_attribute("src")
        target.scroll_into_view_if_needed()
        page.wait_for_function("e => e.complete && e.naturalWidth > 0", arg=target.element_handle())
        assert target.evaluate("e => e.naturalWidth") == -(-n // 3)
        page.locator("button[data-zoom='1']").click()
        assert "/previews/" not in target.get_attribute("src")
        assert target.bounding_box()["width"] == pytest.approx(n, abs=1)  # the full width, 1:1
        page.wait_for_function("e => e.complete && e.naturalWidth > 0", arg=target.element_handle())
        assert target.evaluate("e => e.naturalWidth") == n
        # a flip shows the other side's full image while zoomed
        view = page.locator("#frame-0 .flip[data-own='truth'] .view")
        view.hover()
        flipped = page.locator("#frame-0 .flip[data-own='truth'] img").get_attribute("src")
        assert flipped.endswith("horizon.png") and "/previews/" not in flipped
    assert problems == []


def test_the_renders_wall_time_is_not_a_stage_of_its_own():
    """``technique_frames_s`` is the wall time of the renders the technique rows already show: no row of
    its own, so the stages' shares do not count the renders twice."""
    views = report_columns.technique_views(
        {"techniques": {"horizon": {"label": "horizon map", "file_stem": "horizon"}}}
    )
    timings = {"truth_s": 1.0, "plain_s": 0.5, "horizon_s": 1.5, "technique_frames_s": 2.0, "compare_s": 1.0}
    rows = report_columns.timing_rows(timings, 2, views)
    assert [r for r in rows["rows"] if "technique frames" in r["label"]] == []
    assert rows["stages"] == 4.0


@pytest.mark.parametrize("setup_s, listed", [(2e-5, False), (9.9e-4, False), (1e-3, True), (0.2, True)])
def test_a_set_up_under_a_millisecond_is_named_not_drawn(setup_s, listed):
    """A technique that shares another's kernel sets up in microseconds: its row would say nothing, so
    it is named under the table instead; its renders keep their row, and the shares their sum."""
    views = report_columns.technique_views(
        {"techniques": {"bent-cone": {"label": "bent cone", "file_stem": "bent_cone"}}}
    )
    timings = {"truth_s": 1.0, "bent_cone_setup_s": setup_s, "bent_cone_s": 0.5}
    rows = report_columns.timing_rows(timings, 2, views)
    labels = [r["label"] for r in rows["rows"]]
    assert ("bent cone set-up" in labels) is listed
    assert rows["left_out"] == ([] if listed else ["bent cone set-up"])
    assert "bent cone renders" in labels
    assert rows["stages"] == pytest.approx(1.5 + (setup_s if listed else 0.0))
