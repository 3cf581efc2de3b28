#!/usr/bin/env python3
"""Tile a periodic packing into a larger one (docs/coupled.md "Scaling", the 10^5 and 10^6 rows).

A periodic packing (`sinterdem generate` with `[packing] boundary = "periodic"`) repeated nx x ny x nz
times is again a periodic packing of the larger box, with the same solid fraction and contact
fabric everywhere (no seams: the copies meet exactly as the cell meets its own images). Read as a
walled body (no `periodic_box`), it is a random compact of nx*ny*nz times the particles, which is
how `sinterdem bench coupled --packing FILE` measures the cost of a step at 10^5-10^6 particles
without generating them.

    python3 scripts/tile-packing.py out/periodic-8000/packing.csv out/periodic-8000/summary.json 5 5 5 p1m.csv

prints the new box (m) on stdout.
"""
import csv
import json
import sys


def main(argv):
    if len(argv) != 7:
        sys.exit(__doc__)
    packing, summary, out = argv[1], argv[2], argv[6]
    try:
        n = [int(v) for v in argv[3:6]]
    except ValueError:
        sys.exit(f"tile counts must be integers >= 1, got {argv[3:6]}")
    if min(n) < 1:
        sys.exit(f"tile counts must be integers >= 1, got {n}")
    with open(summary) as f:
        box = json.load(f).get("box_size_m")
    if not box or len(box) != 3:
        sys.exit(f"{summary}: no box_size_m (not a periodic packing)")
    with open(packing, newline="") as f:
        rows = [[float(v) for v in r] for r in list(csv.reader(f))[1:] if r]
    tmp = out + ".part"
    with open(tmp, "w", newline="") as f:
        f.write("x_m,y_m,z_m,radius_m\n")
        for i in range(n[0]):
            for j in range(n[1]):
                for k in range(n[2]):
                    s = (i * box[0], j * box[1], k * box[2])
                    for x, y, z, r in rows:
                        f.write(f"{x + s[0]:.10e},{y + s[1]:.10e},{z + s[2]:.10e},{r:.10e}\n")
    import os

    os.replace(tmp, out)  # atomic: a killed run leaves no half file under the final name
    print(json.dumps({"particles": len(rows) * n[0] * n[1] * n[2], "box_size_m": [box[a] * n[a] for a in range(3)]}))


if __name__ == "__main__":
    main(sys.argv)
