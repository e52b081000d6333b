#!/usr/bin/env python3
"""The ring-compression calibration chart: inner diameter change (%) against
height reduction (%), one curve per shear factor m, from calibration.csv.

  plot_calibration.py DIR        (writes DIR/calibration.png)
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    d = sys.argv[1]
    curves = {}
    with open(os.path.join(d, "calibration.csv")) as f:
        for row in csv.DictReader(f):
            m = float(row["m"])
            curves.setdefault(m, ([0.0], [0.0]))
            curves[m][0].append(float(row["reduction"]))
            curves[m][1].append(float(row["inner_diameter_change"]))
    fig, ax = plt.subplots(figsize=(6.5, 5))
    for m in sorted(curves):
        x, y = curves[m]
        ax.plot(x, y, label=f"m = {m:g}")
        ax.annotate(f"{m:g}", (x[-1], y[-1]), textcoords="offset points", xytext=(4, 0), fontsize=8)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("height reduction (%)")
    ax.set_ylabel("inner diameter change at mid-height (%)")
    ax.set_title("Ring compression 6:3:2, Tresca friction")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "calibration.png"), dpi=130)


if __name__ == "__main__":
    main()
