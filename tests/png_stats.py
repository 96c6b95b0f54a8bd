#!/usr/bin/python3
"""Statistics of a PNG for the figure tests: is it a drawn figure, not a blank page?

usage: png_stats.py [--rows] [--box X0 Y0 X1 Y1] [--border N] FILE [#rrggbb ...]
prints JSON: width, height, distinct colours, the fraction of pixels that differ from the most common
(background) colour, and for each colour asked the number of pixels within 8 levels of it per channel.
With --rows also "rows": for each colour asked, the 5th and 95th percentiles of its pixels' row indices
(top = 0; null without pixels): how far a curve spans vertically, a legend sample aside; and "extent": each
colour's bounding box [row0, row1, col0, col1] over its pixels (null without).
With --box also "box": the colours asked counted only inside the box given as fractions of the width and height
(x0 y0 x1 y1, y from the top), e.g. the plot area of a map.
With --border N also "border_ink": pixels within N pixels of the canvas edge that differ from the background
(text or lines cut by the edge: a figure keeps everything inside its canvas).
"""
import json
import sys

from PIL import Image  # Debian python3-pil (scripts/setup.sh)


def near(c, want):
    return all(abs(a - b) <= 8 for a, b in zip(c, want))


def main():
    args = sys.argv[1:]
    rows = box = border = None
    while args and args[0].startswith("--"):
        if args[0] == "--rows":
            rows, args = True, args[1:]
        elif args[0] == "--box":
            box, args = [float(a) for a in args[1:5]], args[5:]
        elif args[0] == "--border":
            border, args = int(args[1]), args[2:]
        else:
            sys.exit("unknown option " + args[0])
    img = Image.open(args[0]).convert("RGB")
    w, h = img.size
    counts = img.getcolors(maxcolors=w * h)
    counts.sort(reverse=True)
    background = counts[0][1]
    non_bg = sum(n for n, c in counts if c != background)
    out = {"width": w, "height": h, "distinct": len(counts), "non_background": non_bg / float(w * h), "colours": {}}
    wants = {h: tuple(int(h[i:i + 2], 16) for i in (1, 3, 5)) for h in args[1:]}
    for hex_colour, want in wants.items():
        out["colours"][hex_colour] = sum(n for n, c in counts if near(c, want))
    if rows or box:
        pixels = list(img.getdata())
    if rows:
        found = {h: [] for h in wants}
        extent = {h: None for h in wants}
        for k, c in enumerate(pixels):
            for h_, want in wants.items():
                if near(c, want):
                    r, col = k // w, k % w
                    found[h_].append(r)
                    e = extent[h_]
                    extent[h_] = [r, r, col, col] if e is None else [min(e[0], r), max(e[1], r), min(e[2], col),
                                                                      max(e[3], col)]
        out["rows"] = {}
        for h_, r in found.items():
            r.sort()
            out["rows"][h_] = [r[len(r) // 20], r[(len(r) * 19) // 20]] if r else None
        out["extent"] = extent
    if box:
        x0, y0, x1, y1 = int(box[0] * w), int(box[1] * h), int(box[2] * w), int(box[3] * h)
        out["box"] = {h_: 0 for h_ in wants}
        for r in range(max(0, y0), min(h, y1)):
            for c in range(max(0, x0), min(w, x1)):
                p = pixels[r * w + c]
                for h_, want in wants.items():
                    if near(p, want):
                        out["box"][h_] += 1
    if border is not None:
        edge = [(c, r) for r in list(range(border)) + list(range(h - border, h)) for c in range(w)]
        edge += [(c, r) for r in range(border, h - border) for c in list(range(border)) + list(range(w - border, w))]
        ink = sum(1 for xy in edge if img.getpixel(xy) != background)
        out["border_ink"] = ink
    print(json.dumps(out))


if __name__ == "__main__":
    main()
