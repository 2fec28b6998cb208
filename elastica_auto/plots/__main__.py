"""Draw the paper's figures: ``python -m elastica_auto.plots [NAME ...] --data out --out figures``.

Without names, lists the figures (name, paper figure, branch files read). ``all`` draws every
one. Figures read the branch files only. ``--gallery DIR`` writes reduced copies of the PNGs in
``--out`` to DIR (for docs/figures.md).
"""

from __future__ import annotations

import argparse
import sys
import time

from .paper import FIGURES


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m elastica_auto.plots", description=__doc__)
    ap.add_argument("names", nargs="*", help="figure names (see the list), or 'all'")
    ap.add_argument("--data", default="out", help="folder of the runs' .h5 files (default out)")
    ap.add_argument("--out", default="figures", help="folder for the PNG and PDF files")
    ap.add_argument("--gallery", metavar="DIR", help="write reduced copies of the figures' "
                    "PNGs (from --out) to DIR")
    args = ap.parse_args(argv)
    if args.gallery:
        return gallery(args.out, args.gallery)
    if not args.names:
        for f in FIGURES.values():
            print(f"{f.name:<28} paper figure {f.paper:<4} reads {', '.join(f.runs)}")
        return 0
    names = list(FIGURES) if args.names == ["all"] else args.names
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        print(f"unknown figure(s): {', '.join(unknown)}; known: {', '.join(FIGURES)}",
              file=sys.stderr)
        return 2
    for n in names:
        t0 = time.perf_counter()
        paths = FIGURES[n].draw(args.data, args.out)
        print(f"{n}: {', '.join(str(p) for p in paths)} ({time.perf_counter() - t0:.1f} s)")
    return 0


def gallery(fig_dir, dest, width=1500) -> int:
    """Copies of every figure's PNG, at most ``width`` pixels wide, for the docs."""
    from pathlib import Path

    from PIL import Image
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    missing = []
    for f in FIGURES.values():
        src = Path(fig_dir) / f"{f.name.replace('-', '_')}.png"
        if not src.is_file():
            missing.append(str(src))
            continue
        with Image.open(src) as im:
            im = im.convert("RGB")
            if im.width > width:
                im = im.resize((width, round(im.height * width / im.width)), Image.LANCZOS)
            # a 256-colour palette keeps the line art and text crisp at a third of the size
            im.quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(dest / src.name,
                                                                           optimize=True)
        print(f"{src} -> {dest / src.name}")
    if missing:
        print(f"missing (run make figures): {', '.join(missing)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
