"""The comparison's report: a printable table (`format_report`) and a figure (`plot_comparison`)."""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["format_report", "plot_comparison"]

def format_report(result: dict) -> str:
    """The comparison as a printable table (see `compare` for the figures)."""
    c = np.asarray(result["contact_pairs_per_step"])
    o = np.asarray(result["candidates_per_step"])
    mj = np.asarray(result["mujoco_candidates_per_step"])
    lines = [
        f"collide vs MuJoCo {mujoco.__version__}: {result['model']} "
        f"({result['nbody']} bodies, {result['ngeom']} geoms), {result['steps']} steps, "
        f"seed {result['seed']}",
        "",
        f"{'per step':<34}{'mean':>10}{'median':>10}{'max':>10}",
        f"{'MuJoCo contact pairs':<34}{c.mean():>10.1f}{np.median(c):>10.0f}{c.max():>10d}",
        f"{'our candidates':<34}{o.mean():>10.1f}{np.median(o):>10.0f}{o.max():>10d}",
        f"{'MuJoCo broad-phase candidates':<34}{mj.mean():>10.1f}{np.median(mj):>10.0f}"
        f"{mj.max():>10d}",
        "",
        f"recall: {100.0 * result['recall']:.2f} % of {result['contact_pairs_total']} MuJoCo "
        f"contact pairs were among our candidates ({len(result['missed'])} missed)",
    ]
    for miss in result["missed"][:20]:
        lines.append(f"  MISSED step {miss['step']}: {miss['name1']} ({miss['geom1']}) - "
                     f"{miss['name2']} ({miss['geom2']})")
    if len(result["missed"]) > 20:
        lines.append(f"  ... {len(result['missed']) - 20} more")
    lines += [
        "",
        f"median time per step: ours {result['time_ours_us']:.1f} us (Python call included), "
        f"MuJoCo broad phase {result['time_mujoco_broad_us']:.1f} us "
        f"(mjTIMER_COL_BROAD), "
        + (f"ratio {result['ratio']:.2f}x" if np.isfinite(result["ratio"]) else "ratio n/a (MuJoCo's timer read 0)"),
    ]
    ct = result.get("contacts")
    if ct:
        lines += [
            "",
            f"contacts: {ct['matched']} of {ct['mujoco_pairs']} geom pairs MuJoCo made contacts for had ours "
            f"({len(ct['missed'])} missed, {ct['missed_near_touching']} of them within MuJoCo's ccd_tolerance "
            f"{ct['tolerance']:g} of their contact distance; {len(ct['extra'])} of ours beyond MuJoCo's, "
            f"{ct['extra_near_touching']} within it"
            + (f"; {len(ct['skipped'])} left out: a height field or SDF, which collide does not collide"
               if ct.get("skipped") else "")
            + f"); {ct['our_contacts']} contact points against MuJoCo's {ct['mujoco_contacts']}",
            f"  deepest contact of each pair: dist differs by {ct['dist_error_median']:.2g} (median), "
            f"{ct['dist_error_max']:.2g} (max); normals by {ct['normal_error_median_rad']:.2g} rad (median), "
            f"{ct['normal_error_max_rad']:.2g} rad (max)",
        ]
        w = ct.get("dist_error_worst")
        if w:
            lines.append(f"  largest dist difference: step {w['step']}, {w['name1']} ({w['geom1']}) - {w['name2']} "
                         f"({w['geom2']}): MuJoCo {w['dist']:.6g}, ours {w['ours']:.6g}")
        for kind in ("missed", "extra", "skipped"):
            for e in ct.get(kind, [])[:5]:
                lines.append(f"  {kind.upper()} step {e['step']}: {e['name1']} ({e['geom1']}) - {e['name2']} "
                             f"({e['geom2']}), dist {e['dist']:.3g}")
    if result.get("mujoco_count_replayed") is False:
        lines.append("note: the run counting MuJoCo's candidates did not reproduce the timed run's contacts")
    if result.get("flex_contacts_total"):
        lines.append(f"note: {result['flex_contacts_total']} MuJoCo contacts involving a flex were left out "
                     "(collide bounds geoms; flex contacts are not geom pairs)")
    if result.get("unstable_resets"):
        lines.append(f"note: MuJoCo reset an unstable simulation {result['unstable_resets']} time(s)")
    return "\n".join(lines)


def plot_comparison(result: dict, path) -> None:
    """Write a figure of the per-step figures of `compare` (needs matplotlib).

    Top: MuJoCo contact pairs, our candidates and MuJoCo's broad-phase candidates per step;
    bottom: our time and MuJoCo's broad-phase time per step.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    steps = np.arange(result["steps"])
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax1.plot(steps, result["mujoco_candidates_per_step"], lw=0.8,
             label="MuJoCo broad-phase candidates")
    ax1.plot(steps, result["candidates_per_step"], lw=0.8, label="our candidates")
    ax1.plot(steps, result["contact_pairs_per_step"], lw=0.8, label="MuJoCo contact pairs")
    ax1.set_ylabel("geom pairs per step")
    ax1.set_title(f"{result['model']}: recall {100 * result['recall']:.2f} %, "
                  f"{len(result['missed'])} missed", pad=20)  # room for the legend above
    # Outside the axes: the lines fill the panel (MuJoCo's candidates run along its top).
    ax1.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=3, fontsize="small", frameon=False)
    ax2.plot(steps, result["time_mujoco_broad_us_per_step"], lw=0.6,
             label=f"MuJoCo broad phase (median {result['time_mujoco_broad_us']:.1f} us)")
    ax2.plot(steps, result["time_ours_us_per_step"], lw=0.6,
             label=f"ours, Python call included (median {result['time_ours_us']:.1f} us)")
    ax2.set_yscale("log")
    # 2, 5, 10, 20, 50 rather than 2 x 10^0 ... and crowded minor labels
    ax2.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax2.yaxis.set_major_formatter(ScalarFormatter())
    ax2.yaxis.set_minor_formatter(NullFormatter())
    ax2.set_xlabel("step")
    ax2.set_ylabel("time per step (us)")
    ax2.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize="small", frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
