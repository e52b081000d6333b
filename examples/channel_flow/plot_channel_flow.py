#!/usr/bin/env python3
"""PNG figures of the channel_flow example from its CSV files.

Usage: plot_channel_flow.py <results folder> [n]   (needs Debian's python3-matplotlib)
  profile.csv     -> profile.png      (discrete u_h(l/2, y) against the exact u(y))
  convergence.csv -> convergence.png  (log-log L2 error against h, if the file exists)
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], [[float(v) for v in r] for r in rows[1:]]
    return {h: [r[i] for r in data] for i, h in enumerate(header)}


def main(out, n):
    label = f", n = {n}" if n else ""
    d = read(os.path.join(out, "profile.csv"))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    a1.plot(d["u_exact"], d["y"], "k-", lw=1.5, label="exact")
    a1.plot(d["u"], d["y"], "o", ms=3, mfc="none", color="tab:red", label="max-ent, discrete")
    a1.set_xlabel("u")
    a1.set_ylabel("y")
    a1.set_title(f"Velocity across the channel at x = l/2{label}")
    a1.legend()
    umax = max(abs(v) for v in d["u_exact"]) or 1.0
    a2.plot([(u - e) / umax for u, e in zip(d["u"], d["u_exact"])], d["y"], "-", color="tab:blue")
    a2.axvline(0.0, color="0.6", lw=0.8)
    a2.set_xlabel("(u_h - u) / max u")
    a2.set_ylabel("y")
    a2.set_title("Error")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "profile.png"), dpi=150)
    plt.close(fig)

    conv = os.path.join(out, "convergence.csv")
    if os.path.exists(conv):
        c = read(conv)
        h, e = c["h"], c["l2_error"]
        fig, ax = plt.subplots(figsize=(5.5, 4.2))
        ax.loglog(h, e, "o-", label="relative L2 error of u")
        for p in (1, 2):  # reference slopes through the finest point
            ax.loglog(h, [e[-1] * (x / h[-1]) ** p for x in h], "--", lw=0.8, label=f"slope {p}")
        if len(h) > 1:
            r = math.log(e[-2] / e[-1]) / math.log(h[-2] / h[-1])
            ax.set_title(f"Channel flow{label}: last L2 rate {r:.2f}")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xticks(h)
        ax.set_xticklabels([f"{x:.3g}" for x in h])
        ax.set_xlabel("h")
        ax.set_ylabel("L2 error")
        ax.legend()
        ax.grid(True, which="both", lw=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(out, "convergence.png"), dpi=150)
        plt.close(fig)
    print(f"plot_channel_flow: PNG figures in {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/channel_flow",
         sys.argv[2] if len(sys.argv) > 2 else "")
