"""A run's metrics in words: the summary `run` prints (the metrics themselves are
`bwr_twin.sim.metrics`')."""

from __future__ import annotations

from bwr_twin.model.machine import AXES, UNITS, to_display


def summary_table(metrics: dict) -> str:
    """The maximum errors with their times, in engineering units (m, deg)."""
    lines = [
        f"{'axis':<7} {'position error max':>24} {'velocity error max':>26} {'acceleration error max':>30} {'pos. RMS':>12}"
    ]
    for j, axis in enumerate(AXES):
        m = metrics[axis]
        lines.append(
            f"{axis:<7} {_largest(m, j, 'position', ''):>24} {_largest(m, j, 'velocity', '/s'):>26} "
            f"{_largest(m, j, 'acceleration', '/s^2'):>30} {to_display(j, m['position_error_rms']):>9.4g} {UNITS[j]}"
        )
    lines.append(f"largest CP distance from its desired position: {metrics['cp_error_max']:.4g} m @ {metrics['cp_error_max_time']:.1f} s")
    reclaim = metrics.get("reclaim")
    if reclaim is not None:
        load = reclaim["digging_force_max_N"]
        lines.append(
            f"reclaimed {reclaim['mass_t']:.1f} t ({reclaim['volume_m3']:.1f} m³): mean {reclaim['rate_mean_tph']:.0f} t/h "
            f"over {reclaim['carrying_time_s']:.0f} s of carrying, CV {reclaim['rate_cv']:.2f}, peak "
            f"{reclaim['rate_max_tph']:.0f} t/h; spilled {reclaim['spill_t']:.1f} t"
            + (f"; digging load up to {load / 1e3:.0f} kN" if load > 0 else "")
        )
        if "target_rate_tph" in reclaim:
            lines.append(plan_line(reclaim))
        if reclaim["spill_t"] > 0:
            lines.append(f"warning: the wheel dug more than its buckets hold: {reclaim['spill_t']:.1f} t spilled")
    lines += [f"warning: {flag}" for flag in metrics.get("limits", ())]
    return "\n".join(lines)


def plan_line(reclaim: dict) -> str:
    """How a bench plan was carried out: the rate in steady cutting against its target, the
    landing, the over-cut and the tonnes of each bench."""
    target, steady = reclaim["target_rate_tph"], reclaim["steady_time_s"]
    if steady > 0:
        rate = (f"steady cutting {steady:.0f} s at {reclaim['steady_rate_mean_tph']:.0f} t/h "
                f"({100 * (reclaim['steady_rate_mean_tph'] / target - 1):+.1f} % of the {target:.0f} t/h target), "
                f"CV {reclaim['steady_rate_cv']:.3f}, {100 * reclaim['steady_within_10pct']:.0f} % of it within ±10 %")
    else:
        rate = f"no steady cutting (target {target:.0f} t/h)"
    landing = reclaim["landing_error_m"]
    benches = ", ".join(f"{t:.0f}" for t in reclaim["bench_t"])
    return (f"{rate}; landing error {landing:.3f} m; over-cut up to {reclaim['overcut_max_m']:.2f} m; "
            f"bench tonnes {benches} t" if landing is not None else f"{rate}; the wheel never met the pile")


def _largest(axis_metrics: dict, j: int, kind: str, per: str) -> str:
    """'+0.01812 m @ 204.1 s': the largest error of one kind, in engineering units, and its time."""
    value, time = axis_metrics[f"{kind}_error_max"], axis_metrics[f"{kind}_error_max_time"]
    return f"{to_display(j, value):+.4g} {UNITS[j]}{per} @ {time:5.1f} s"
