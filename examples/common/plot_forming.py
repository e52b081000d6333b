#!/usr/bin/env python3
"""PNG figures of a forming run written by maxentflow's ResultsWriter.

  plot_forming.py DIR --maps pressure:1,50,100 velocity_y:100 \
                      --force-tool "top plate" [--exact exact.csv] \
                      [--profile profile_axis_step1.csv ...] [--mesh 100] [--cutting]

Maps: tripcolor of a VTU point field over the kept triangles (the integration
mesh), with the tools' outlines from tools.csv; `velocity_x` / `velocity_y` pick
a component. Curve: the tool force against its stroke from forces.csv, with the
exact curve if given. Profiles: a two-column CSV (position, value) as a line,
like the paper's Fig. 7 (name.csv -> name.png). Mesh: the node cloud with its
integration mesh (alpha-shape) at a step. Cutting: Fc and Ft against time
(cutting_forces.csv) and the chip thickness against the cut length (chip.csv).
Power: where the tools' power goes (power.csv), whenever the run wrote it.
"""
import argparse
import csv
import os
import sys
import xml.etree.ElementTree as ET

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.tri as mtri  # noqa: E402


def read_vtu(path):
    root = ET.parse(path).getroot()
    piece = root.find("UnstructuredGrid/Piece")
    def values(node):
        return [float(v) for v in node.text.split()]
    pts = values(piece.find("Points/DataArray"))
    x, y = pts[0::3], pts[1::3]
    conn = [int(v) for v in piece.find("Cells/DataArray[@Name='connectivity']").text.split()]
    tris = [conn[i:i + 3] for i in range(0, len(conn), 3)]
    fields = {}
    for da in piece.find("PointData"):
        comps = int(da.get("NumberOfComponents", "1"))
        v = values(da)
        if comps == 1:
            fields[da.get("Name")] = v
        else:
            for c, s in enumerate("xyz"[:comps]):
                fields[da.get("Name") + "_" + s] = v[c::comps]
    return x, y, tris, fields


def read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def tool_outlines(directory, step):
    path = os.path.join(directory, "tools.csv")
    if not os.path.exists(path):
        return {}
    out = {}
    for r in read_csv(path):
        if int(r["step"]) == step:
            out.setdefault(r["tool"], ([], []))
            out[r["tool"]][0].append(float(r["x"]))
            out[r["tool"]][1].append(float(r["y"]))
    return out


LABELS = {"pressure": "pressure p", "velocity_x": "horizontal velocity", "velocity_y": "vertical velocity",
          "strain_rate": "equivalent strain rate", "effective_strain": "effective strain"}


def plot_map(directory, prefix, field, step):
    vtu = os.path.join(directory, "%s_%04d.vtu" % (prefix, step))
    if not os.path.exists(vtu):
        print("plot_forming: no %s, skipped" % vtu, file=sys.stderr)
        return
    x, y, tris, fields = read_vtu(vtu)
    tri = mtri.Triangulation(x, y, tris)
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    v = fields[field]
    lo, hi = min(v), max(v)
    scale = max(abs(lo), abs(hi), 1e-300)
    if hi - lo <= 1e-6 * scale:  # uniform up to round-off: show one colour, not the noise
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.01 * scale, mid + 0.01 * scale
    pc = ax.tripcolor(tri, v, shading="gouraud", cmap="jet", vmin=lo, vmax=hi)
    ax.triplot(tri, color="k", lw=0.15, alpha=0.35)
    xmin, xmax, ymin, ymax = min(x), max(x), min(y), max(y)
    pad = 0.08 * max(xmax - xmin, ymax - ymin)
    for name, (tx, ty) in tool_outlines(directory, step).items():
        ax.plot(tx, ty, color="0.3", lw=2.5)
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    fig.colorbar(pc, ax=ax, label=LABELS.get(field, field))
    ax.set_title("%s, step %d" % (LABELS.get(field, field), step))
    fig.tight_layout()
    out = os.path.join(directory, "%s_step%d.png" % (field, step))
    fig.savefig(out, dpi=130)
    plt.close(fig)


def plot_force(directory, tool, exact):
    rows = [r for r in read_csv(os.path.join(directory, "forces.csv")) if r["tool"] == tool]
    if not rows:
        return
    stroke = [float(r["stroke"]) for r in rows]
    fx = [float(r["fx"]) for r in rows]
    fy = [float(r["fy"]) for r in rows]
    use_y = max(abs(v) for v in fy) >= max(abs(v) for v in fx)
    # The load a press reads: the main component, positive where the tool
    # pushes the workpiece (forces.csv keeps the signed force on the tool).
    f = fy if use_y else fx
    sign = -1.0 if max(f, key=abs) < 0 else 1.0
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot(stroke, [sign * v for v in f], "o-", ms=3, label="maxentflow")
    if exact:
        e = read_csv(os.path.join(directory, exact))
        ax.plot([float(r["stroke"]) for r in e], [sign * float(r["force_exact"]) for r in e], "k--",
                label="exact (homogeneous flow)")
    ax.set_xlabel("stroke")
    ax.set_ylabel("load on the %s (%s%s, as a press reads it)" % (tool, "-" if sign < 0 else "", "F_y" if use_y else "F_x"))
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "force_stroke.png"), dpi=130)
    plt.close(fig)


def plot_power(directory):
    """power.csv: the tools' power against time and where it goes (plastic and
    stabilization dissipation), with the stabilization's share below."""
    path = os.path.join(directory, "power.csv")
    if not os.path.exists(path):
        return
    rows = read_csv(path)
    if not rows:
        return
    t = [float(r["time"]) for r in rows]
    tool = [float(r["tool_power"]) for r in rows]
    plastic = [float(r["plastic_power"]) for r in rows]
    stab = [float(r["stabilization_power"]) for r in rows]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(6.4, 5.6), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(t, tool, "o-", ms=3, label="tools (load x speed)")
    ax.plot(t, plastic, "-", label="plastic dissipation")
    ax.plot(t, stab, "-", label="stabilization's dissipation")
    ax.set_ylabel("power")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax2.plot(t, [100 * s / p if p else 0.0 for s, p in zip(stab, tool)], "-")
    ax2.set_xlabel("time")
    ax2.set_ylabel("stabilization / tools, %")
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "power.png"), dpi=130)
    plt.close(fig)


PROFILE_TITLES = {"profile_axis_step1": "pressure along the axis y = 0, step 1",
                  "profile_die_step1": "pressure along the die face plane x = L, step 1"}


def plot_profile(directory, name):
    path = os.path.join(directory, name)
    if not os.path.exists(path):
        print("plot_forming: no %s, skipped" % path, file=sys.stderr)
        return
    rows = read_csv(path)
    xk, yk = list(rows[0].keys())[:2]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot([float(r[xk]) for r in rows], [float(r[yk]) for r in rows], "-", lw=1.8)
    ax.set_xlabel(xk)
    ax.set_ylabel("pressure p" if yk == "p" else yk)
    stem = os.path.splitext(name)[0]
    ax.set_title(PROFILE_TITLES.get(stem, stem))
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, stem + ".png"), dpi=130)
    plt.close(fig)


def plot_mesh(directory, prefix, step):
    vtu = os.path.join(directory, "%s_%04d.vtu" % (prefix, step))
    if not os.path.exists(vtu):
        print("plot_forming: no %s, skipped" % vtu, file=sys.stderr)
        return
    x, y, tris, _ = read_vtu(vtu)
    fig, ax = plt.subplots(figsize=(7.2, 5.2))
    ax.triplot(mtri.Triangulation(x, y, tris), color="tab:blue", lw=0.4)
    ax.plot(x, y, "k.", ms=2)
    for name, (tx, ty) in tool_outlines(directory, step).items():
        ax.plot(tx, ty, color="0.3", lw=2.5)
    ax.set_aspect("equal")
    ax.set_title("nodes and integration mesh, step %d (%d nodes)" % (step, len(x)))
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "mesh_step%d.png" % step), dpi=130)
    plt.close(fig)


def plot_cutting(directory):
    path = os.path.join(directory, "cutting_forces.csv")
    if os.path.exists(path):
        rows = read_csv(path)
        t = [float(r["time"]) for r in rows]
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        ax.plot(t, [float(r["Fc"]) for r in rows], "-", label="cutting force Fc")
        ax.plot(t, [float(r["Ft"]) for r in rows], "-", label="thrust force Ft")
        ax.set_xlabel("time")
        ax.set_ylabel("force per unit depth")
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(directory, "cutting_forces.png"), dpi=130)
        plt.close(fig)
    path = os.path.join(directory, "chip.csv")
    if os.path.exists(path):
        rows = read_csv(path)
        if rows:
            fig, ax = plt.subplots(figsize=(6.4, 4.4))
            ax.plot([float(r["cut_length"]) for r in rows], [float(r["chip_thickness"]) for r in rows], "o-", ms=2)
            ax.set_xlabel("cut length")
            ax.set_ylabel("chip thickness")
            ax.grid(True, alpha=0.3)
            fig.tight_layout()
            fig.savefig(os.path.join(directory, "chip_thickness.png"), dpi=130)
            plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("directory")
    ap.add_argument("--prefix", default="step")
    ap.add_argument("--maps", nargs="*", default=[], help="field:step,step,...")
    ap.add_argument("--force-tool")
    ap.add_argument("--exact")
    ap.add_argument("--profile", nargs="*", default=[], help="two-column CSV files to draw as curves")
    ap.add_argument("--mesh", type=int, nargs="*", default=[], help="steps to draw the nodes and mesh of")
    ap.add_argument("--cutting", action="store_true", help="cutting forces and chip thickness")
    a = ap.parse_args()
    for spec in a.maps:
        field, steps = spec.split(":")
        for s in steps.split(","):
            plot_map(a.directory, a.prefix, field, int(s))
    if a.force_tool:
        plot_force(a.directory, a.force_tool, a.exact)
    for name in a.profile:
        plot_profile(a.directory, name)
    for step in a.mesh:
        plot_mesh(a.directory, a.prefix, step)
    if a.cutting:
        plot_cutting(a.directory)
    plot_power(a.directory)


if __name__ == "__main__":
    main()
