#!/usr/bin/python3 -s
"""Draws the paper's Fig. 4 from deskew_metrics' figure CSVs: raw points red, corrected green, true
walls black, the laser's path during the sweep as a black line, in the laser frame at the reference time.

usage: plot_paper_figures.py WORK_DIR OUT_DIR
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# sensor -> half-width [m] of its panels (the LDS-01 sees 3.5 m, in the small room)
SENSORS = {"UTM-30LX": 9.0, "ILD26TRI": 9.0, "UTM-30LX-270": 9.0, "LDS-01": 3.0}
MOTIONS = ["translation", "rotation", "arc"]


def read(path):
    data = {"wall": [], "path": [], "raw": [], "corrected": []}
    with open(path) as handle:
        for row in csv.DictReader(handle):
            kind = row["kind"]
            if kind == "wall":
                data["wall"].append(tuple(float(row[k]) for k in ("x", "y", "x2", "y2")))
            elif kind in data:
                data[kind].append((float(row["x"]), float(row["y"])))
    return data


def panel(axes, data, title, view=9.0):
    for x1, y1, x2, y2 in data["wall"]:
        axes.plot([x1, x2], [y1, y2], color="black", linewidth=0.8)
    for kind, colour in (("raw", "red"), ("corrected", "green")):
        points = data[kind]
        axes.scatter([p[0] for p in points], [p[1] for p in points], s=2.5, color=colour, label=kind,
                     linewidths=0, rasterized=True)
    path = data["path"]
    axes.plot([p[0] for p in path], [p[1] for p in path], color="black", linewidth=1.5)
    axes.set_xlim(-view, view)
    axes.set_ylim(-view, view)
    axes.set_aspect("equal")
    axes.set_title(title, fontsize=8)
    axes.tick_params(labelsize=6)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    work, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    for speed in ("normal", "high"):
        figure, axes = plt.subplots(len(SENSORS), 3, figsize=(10, 10 * len(SENSORS) / 3))
        for row, (sensor, view) in enumerate(SENSORS.items()):
            for column, motion in enumerate(MOTIONS):
                path = os.path.join(work, f"{sensor}_{speed}_{motion}-on.csv")
                if not os.path.exists(path):  # not a suite case (LDS-01 at high speed in a line)
                    axes[row][column].axis("off")
                    continue
                panel(axes[row][column], read(path), f"{sensor}, {speed} speed, {motion}", view)
        axes[0][0].legend(loc="lower left", fontsize=7, markerscale=6)
        figure.tight_layout()
        figure.savefig(os.path.join(out, f"paper_{speed}.png"), dpi=90)
        plt.close(figure)
    figure, axes = plt.subplots(1, 1, figsize=(5, 5))
    panel(axes, read(os.path.join(work, "ILD26TRI_varying_varying-on.csv")), "ILD26TRI, varying speed and turn")
    axes.legend(loc="lower left", fontsize=7, markerscale=6)
    figure.tight_layout()
    figure.savefig(os.path.join(out, "paper_varying.png"), dpi=110)
    plt.close(figure)


if __name__ == "__main__":
    main()
