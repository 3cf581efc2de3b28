#!/usr/bin/env python3
"""The seed paper's two statements with sliding on and off (docs/coupled.md, issue 36 item 6):
box shrinkage of every axis at the end of the bundled compacts and cells, sliding "none" and
"viscous", against their pair. Reads DIR/<run>/summary.json of the runs named below (the commands
are in docs/coupled.md) and writes OUT.svg, OUT.csv (and OUT.png when ImageMagick's `convert` renders
it). No third-party modules.

    python3 scripts/seed_statements_sliding.py DIR docs/figures/seed-statements-sliding
"""
import json
import os
import shutil
import subprocess
import sys

GROUPS = [
    ("copper, 1293 K, 5000 s (Fig. 11)", "pairCu", [("none", "cuN"), ("viscous", "cuV")]),
    ("E14B compact, new contacts (Fig. 19)", "pairTi", [("none", "tiN"), ("viscous", "tiV")]),
    ("E14B RVE, new contacts", "pairTi32", [("none", "rveTiN"), ("viscous", "rveTiV")]),
]


def main(src, out):
    rows, bars = [], []
    for label, pair, runs in GROUPS:
        p = 100.0 * json.load(open(os.path.join(src, pair, "summary.json")))["shrinkage"]
        rows.append((label, "pair", p, p, p))
        group = [("pair", [p])]
        for name, d in runs:
            s = json.load(open(os.path.join(src, d, "summary.json")))
            xyz = [100.0 * s["shrinkage_" + a] for a in "xyz"]
            rows.append((label, name, *xyz))
            group.append((name, xyz))
        bars.append((label, group))
    with open(out + ".csv", "w") as f:
        f.write("group,run,shrinkage_x_percent,shrinkage_y_percent,shrinkage_z_percent\n")
        for r in rows:
            f.write('"%s",%s,%.4f,%.4f,%.4f\n' % r)
    top = max(max(v) for _, g in bars for _, vs in g for v in [vs]) * 1.15
    w, h, left, bottom, plot_h = 900, 420, 70, 60, 300
    gw = (w - left - 20) / len(bars)
    colours = {"pair": "#444444", "none": "#1f77b4", "viscous": "#d62728"}
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>',
           f'<text x="{w/2}" y="20" text-anchor="middle" font-size="14">Box shrinkage at the end: pair, sliding "none", sliding "viscous" (x, y, z)</text>']
    y0 = h - bottom
    for k in range(0, int(top) + 1):
        y = y0 - plot_h * k / top
        svg.append(f'<line x1="{left}" x2="{w-20}" y1="{y:.1f}" y2="{y:.1f}" stroke="#dddddd"/>')
        svg.append(f'<text x="{left-6}" y="{y+4:.1f}" text-anchor="end">{k} %</text>')
    for gi, (label, group) in enumerate(bars):
        x = left + gi * gw + 15
        for name, vs in group:
            for v in vs:
                bh = plot_h * v / top
                svg.append(f'<rect x="{x:.1f}" y="{y0-bh:.1f}" width="16" height="{bh:.1f}" fill="{colours[name]}"/>')
                x += 18
            svg.append(f'<text x="{x-9*len(vs)-1:.1f}" y="{y0+14}" text-anchor="middle" font-size="10">{name}</text>')
            x += 14
        svg.append(f'<text x="{left + gi*gw + gw/2:.1f}" y="{y0+34}" text-anchor="middle">{label}</text>')
    svg.append(f'<line x1="{left}" x2="{w-20}" y1="{y0}" y2="{y0}" stroke="black"/>')
    svg.append("</svg>")
    with open(out + ".svg", "w") as f:
        f.write("\n".join(svg) + "\n")
    if shutil.which("convert"):
        # a stand-in `convert` may not render SVG: the PNG is optional
        if subprocess.run(["convert", out + ".svg", out + ".png"], capture_output=True).returncode != 0:
            print(f"{out}.png not written (convert could not render the SVG); {out}.svg and .csv are")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
