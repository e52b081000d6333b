#!/usr/bin/env python3
"""PNG figures of the basis_functions example (paper Figs. 1-3) from its CSV files.

Usage: plot_basis_functions.py <results folder>   (needs Debian's python3-matplotlib)
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], [[float(v) for v in r] for r in rows[1:]]
    return header, {h: [r[i] for r in data] for i, h in enumerate(header)}


def main(out):
    # Fig. 1: gamma varying across the axis.
    header, d = read(os.path.join(out, "fig1_gamma_varying.csv"))
    _, nodes = read(os.path.join(out, "fig1_nodes.csv"))
    fig, ax = plt.subplots(figsize=(9, 3.2))
    for h in header[1:]:
        ax.plot(d["x"], d[h], lw=1.2)
    ax.plot(nodes["x"], [0] * len(nodes["x"]), "ko", ms=4)
    for g, x0 in zip([0.5, 1.0, 1.5, 2.5, 4.0], [2, 6, 10, 14, 18]):
        ax.text(x0, 1.02, f"$\\gamma$={g}", ha="center")
    ax.set_ylim(-0.03, 1.1)
    ax.set_xlabel("x")
    ax.set_ylabel("$p_a(x)$")
    ax.set_title("Local max-ent basis: from meshfree to Delaunay as $\\gamma$ grows (paper Fig. 1)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig1_gamma_varying.png"), dpi=150)
    plt.close(fig)

    # Fig. 2: functions and derivatives, gamma = 0.8.
    header, d = read(os.path.join(out, "fig2_gamma0.8.csv"))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.6))
    for h in header[1:]:
        (a1 if h.startswith("p") else a2).plot(d["x"], d[h], lw=1.1)
    a1.set_title("$p_a(x)$, $\\gamma$ = 0.8")
    a2.set_title("$dp_a/dx$, $\\gamma$ = 0.8")
    for a in (a1, a2):
        a.set_xlabel("x")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig2_gamma0.8.png"), dpi=150)
    plt.close(fig)

    # Fig. 3: an interior and a boundary node's function in 2-D.
    _, d = read(os.path.join(out, "fig3_2d.csv"))
    import matplotlib.tri as mtri

    tri = mtri.Triangulation(d["x"], d["y"])
    fig = plt.figure(figsize=(11, 4.6))
    for k, (name, title) in enumerate([("p_interior", "interior node (0.5, 0.5)"),
                                       ("p_boundary", "boundary node (0.5, 0)")]):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.plot_trisurf(tri, d[name], cmap="viridis", linewidth=0)
        ax.set_title(f"$p_a$ of the {title}, $\\gamma$ = 1.6")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.view_init(elev=28, azim=-60)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig3_2d.png"), dpi=150)
    plt.close(fig)
    print(f"plot_basis_functions: PNG figures in {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/basis_functions")
