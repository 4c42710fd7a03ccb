#!/usr/bin/python3 -s
"""Before/after figures of the demo: raw points red, corrected green.

usage: plot_demo.py turn CSV OUT.png TITLE     two consecutive scans in the odom frame while turning
       plot_demo.py scan CSV OUT.png TITLE     one simulated scan with the true walls (deskew_metrics CSV)
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def turn(path, out, title):
    data = {}
    for row in rows(path):
        data.setdefault(row["kind"], []).append((float(row["x"]), float(row["y"])))
    figure, axes = plt.subplots(1, 2, figsize=(10, 5), sharex=True, sharey=True)
    for panel, (name, colour) in zip(axes, (("raw", "red"), ("corrected", "green"))):
        for suffix, marker in (("_a", "o"), ("_b", "^")):
            points = data.get(name + suffix, [])
            panel.scatter([p[0] for p in points], [p[1] for p in points], s=6, color=colour, marker=marker,
                          alpha=0.7 if suffix == "_a" else 1.0, label=f"{name} scan {'k' if suffix == '_a' else 'k+1'}")
        panel.set_aspect("equal")
        panel.legend(fontsize=7, loc="lower left")
        panel.set_title(f"{name}: two consecutive scans in odom", fontsize=9)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    figure.savefig(out, dpi=90)


def scan(path, out, title):
    figure, axes = plt.subplots(1, 1, figsize=(6, 6))
    kinds = {"raw": [], "corrected": [], "path": []}
    for row in rows(path):
        if row["kind"] == "wall":
            axes.plot([float(row["x"]), float(row["x2"])], [float(row["y"]), float(row["y2"])], color="black",
                      linewidth=0.8)
        elif row["kind"] in kinds:
            kinds[row["kind"]].append((float(row["x"]), float(row["y"])))
    for kind, colour in (("raw", "red"), ("corrected", "green")):
        axes.scatter([p[0] for p in kinds[kind]], [p[1] for p in kinds[kind]], s=4, color=colour, label=kind,
                     linewidths=0)
    axes.plot([p[0] for p in kinds["path"]], [p[1] for p in kinds["path"]], color="black", linewidth=1.5)
    axes.set_xlim(-9, 9)
    axes.set_ylim(-9, 9)
    axes.set_aspect("equal")
    axes.legend(fontsize=7, loc="lower left", markerscale=3)
    axes.set_title(title, fontsize=9)
    figure.tight_layout()
    figure.savefig(out, dpi=90)


if __name__ == "__main__":
    if len(sys.argv) != 5 or sys.argv[1] not in ("turn", "scan"):
        sys.exit(__doc__)
    {"turn": turn, "scan": scan}[sys.argv[1]](sys.argv[2], sys.argv[3], sys.argv[4])
