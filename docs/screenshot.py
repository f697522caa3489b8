"""Regenerate docs/report.png, the picture the README leads with (the top of a sweep's report), and
docs/suite.png (the top of ``hzval suite``'s overview).

Runs the README's main job, ``hzval sweep`` on the built-in bricks, from the
repository root (it writes ``reports/bricks``; or takes the report of an
existing sweep folder given with ``--from``), opens its ``index.html`` in
Debian's chromium through Playwright (no download) and saves the first
screenful, then one frame's panels, stacked into one PNG.

With ``--suite DIR`` it saves the first screenful of the suite overview in
``DIR`` (``hzval suite --out DIR``, the built-in materials) instead.

Usage (from the repository root)::

    .venv/bin/python docs/screenshot.py [--from reports/bricks] [--out docs/report.png]
    .venv/bin/python docs/screenshot.py --suite reports/suite [--out docs/suite.png]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from", dest="source", type=Path, default=None, help="an existing sweep folder")
    ap.add_argument("--suite", type=Path, default=None, help="a folder hzval suite wrote: shoot its overview")
    ap.add_argument(
        "--out", type=Path, default=None, help="the PNG (default docs/report.png or docs/suite.png)"
    )
    args = ap.parse_args(argv)
    if args.suite is not None:
        return _suite(args.suite, args.out or Path(__file__).with_name("suite.png"))
    args.out = args.out or Path(__file__).with_name("report.png")

    from PIL import Image
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.source
        if folder is None:
            root = Path(__file__).resolve().parent.parent
            subprocess.run(
                [sys.executable, "-m", "hzval", "sweep"], check=True, cwd=root, stdout=subprocess.DEVNULL
            )
            folder = root / "reports" / "bricks"
        shots = []
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1440, "height": 900}, device_scale_factor=1)
            page.goto((folder / "index.html").resolve().as_uri(), wait_until="load")
            top = Path(tmp) / "top.png"
            page.screenshot(path=str(top))
            frame = Path(tmp) / "frame.png"
            card = page.locator("#frame-4")
            card.scroll_into_view_if_needed()
            page.wait_for_function(
                "id => [...document.querySelectorAll('#' + id + ' img')]"
                ".every(i => i.complete && i.naturalWidth > 0)",
                arg="frame-4",
            )
            card.evaluate("e => e.scrollIntoView({block: 'start'})")
            page.wait_for_timeout(500)  # let the panels lay out and paint
            box = card.bounding_box()  # viewport coordinates, once scrolled to the top
            page.screenshot(
                path=str(frame),
                clip={
                    "x": box["x"],
                    "y": max(box["y"], 0),
                    "width": box["width"],
                    "height": min(box["height"], 900 - max(box["y"], 0)),
                },
            )
            browser.close()
            shots = [Image.open(top), Image.open(frame)]
        width = max(s.width for s in shots)
        sheet = Image.new("RGB", (width, sum(s.height for s in shots)), (31, 31, 34))
        y = 0
        for s in shots:
            sheet.paste(s, (0, y))
            y += s.height
        args.out.parent.mkdir(parents=True, exist_ok=True)
        tmp_out = args.out.with_suffix(".tmp.png")
        sheet.save(tmp_out, optimize=True)
        tmp_out.replace(args.out)
    print(f"wrote {args.out} ({sheet.width} x {sheet.height})")
    return 0


def _suite(folder: Path, out: Path) -> int:
    """The overview's table and its first cards, 1440 x 1000."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1440, "height": 1000}, device_scale_factor=1)
        page.goto((folder / "index.html").resolve().as_uri(), wait_until="load")
        page.wait_for_function(
            "[...document.images].slice(0, 12).every(i => i.complete && i.naturalWidth > 0)"
        )
        tmp_out = out.with_suffix(".tmp.png")
        page.screenshot(path=str(tmp_out))
        browser.close()
    tmp_out.replace(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
