"""A run's metrics in words: the summary `run` prints (the metrics themselves are
`bwr_twin.sim.metrics`')."""

from __future__ import annotations

import math

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
        # Two CVs (std/mean, without unit) follow on these lines: of the rate while the belt
        # carries, and of the rate in steady cutting; each says which.
        lines.append(
            f"reclaimed {reclaim['mass_t']:.1f} t ({reclaim['volume_m3']:.1f} m³): "
            f"mean {reclaim['rate_mean_tph']:.0f} t/h over {reclaim['carrying_time_s']:.0f} s of carrying, "
            f"peak {reclaim['rate_max_tph']:.0f} t/h, reclaim rate CV while carrying (std/mean) "
            f"{reclaim['rate_cv']:.2f}; spilled {reclaim['spill_t']:.1f} t"
            + (f"; digging load up to {load / 1e3:.0f} kN" if load > 0 else "")
            + (f"; the cut faces slumped {reclaim['slumped_m3']:,.0f} m³" if "slumped_m3" in reclaim else "")
        )
        if "target_rate_tph" in reclaim:
            lines.append(plan_line(reclaim))
        if reclaim["spill_t"] > 0:
            lines.append(f"warning: the wheel dug more than its buckets hold: {reclaim['spill_t']:.1f} t spilled")
    stacking = metrics.get("stacking")
    if stacking is not None:
        lines.append(stacking_line(stacking))
    blend = metrics.get("blend")
    if blend is not None:
        lines.append(blend_line(blend))
    scan = metrics.get("scan")
    if scan is not None and scan.get("plan_start") is not None:
        lines.append(scan_line("the benches planned on the scanned pile", scan["plan_start"]))
    collision = metrics.get("collision")
    if collision is not None:
        lines += clearance_line(collision).splitlines()
        lines += [f"warning: {contact_line(contact)}" for contact in collision["contacts"]]
        if collision["interventions"]:
            lines.append("interlock: " + ", ".join(intervention_text(i) for i in collision["interventions"]))
    for fault in metrics.get("faults", ()):
        lines.append(fault_line(fault))
    lines += [f"warning: {flag}" for flag in metrics.get("limits", ())]
    return "\n".join(lines)


def pattern_text(pattern: str, layers: int) -> str:
    """What a pattern's `layers` counts, in words: "32 chevron layers", "5 windrow rows across"."""
    return {"chevron": f"{layers} chevron layers", "windrow": f"{layers} windrow rows across",
            "strata": f"{layers} strata", "cone_shell": f"{layers} cone shells"}[pattern]


def stacking_line(stacking: dict) -> str:
    """What a stacking run laid, the grade it came at, and the balance of tonnes."""
    name = stacking["grade_name"]
    return (f"stacked {stacking['tonnes_in_t']:,.1f} t in {pattern_text(stacking['pattern'], stacking['layers'])} "
            f"({stacking['deposits']} deposits): crest {stacking['crest_height_m']:.2f} m (target "
            f"{stacking['target_height_m']:.2f} m); grade in {stacking['grade_in_mean']:.3f} ± "
            f"{stacking['grade_in_sd']:.3f} {name}; the stream fell {stacking['drop_min_m']:.1f}-"
            f"{stacking['drop_max_m']:.1f} m, {stacking['drop_mean_m']:.1f} m on average ({stacking['drop_target_m']:g} m "
            f"planned above each layer's crest); the pile holds {stacking['pile_t']:,.1f} t "
            f"(balance {stacking['balance_relative']:.1e})")


def blend_line(blend: dict) -> str:
    """The grade that left a stacked pile against what was stacked, and the band."""
    name = blend["grade_name"]
    band = blend["band"]
    outside = (f"; outside the {band[0]:g}-{band[1]:g} {name} band for {blend['longest_outside_band_s']:.1f} s "
               "at most" if band is not None else "")
    return (f"blended: {blend['tonnes_out_t']:,.1f} t out at {blend['grade_out_mean']:.3f} ± "
            f"{blend['grade_out_sd']:.3f} {name} (stacked at {blend['grade_in_mean']:.3f} ± "
            f"{blend['grade_in_sd']:.3f} in {pattern_text(blend['pattern'], blend['layers'])}): sd ratio "
            f"{blend['sd_ratio']:.3f}, {law_text(blend['equivalent_layers'])}{outside}; balance {blend['balance_relative']:.1e}")


def law_text(layers: float) -> str:
    """1/sqrt(N) for the N equal layers a pattern's passes amount to; none for cone shells."""
    if math.isnan(layers):
        return "no 1/sqrt(N): the cones do not run the pile's length"
    return f"1/sqrt(N) {1 / math.sqrt(layers):.3f}" + ("" if layers == round(layers) else f" (N = {layers:.1f})")


def intervention_text(intervention: dict) -> str:
    """An interlock's intervention in words: its kind and time, and what it names of the cause
    (an engineer's interlock reports at least the kind and the time)."""
    text = f"{intervention['kind'].replace('_', ' ')} at {intervention['time_s']:.2f} s"
    if "encoder_apart_m" in intervention:
        return text + f" ({intervention['axis']} encoder {intervention['encoder_apart_m']:.2f} m off its drive)"
    if "predicted_clearance_m" in intervention:
        return text + f" ({intervention.get('part', 'a shape')} {intervention['predicted_clearance_m']:.2f} m predicted)"
    return text


def scan_line(when: str, known: dict) -> str:
    """The scanned pile's tonnes against the truth over the cells seen (bwr_twin.sensing.survey)."""
    return (f"{when} at {known['time_s']:.1f} s: {known['scanned_t']:,.0f} t scanned against {known['true_t']:,.0f} t "
            f"true over the cells seen ({100 * known['error_share']:+.2f} %), "
            f"{100 * known['footprint_seen_share']:.0f} % of the pile's footprint seen")


def clearance_line(collision: dict) -> str:
    """The least clearance of each collision shape to the pile (bwr_twin.collision.monitor), and
    of the nearest pair of shapes to a neighbour's (bwr_twin.collision.machines)."""
    watch = collision["watch_m"]
    parts = [f"{part} {'>= ' if least['clearance_m'] >= watch else ''}{least['clearance_m']:.2f} m"
             + (f" @ {least['time_s']:.1f} s" if least["clearance_m"] < watch else "")
             for part, least in collision["pile"].items()]
    lines = ["least clearance to the pile: " + ", ".join(parts)] if parts else []
    machines = collision.get("machines")
    if machines:  # the nearest pair of the two machines' shapes
        pair, least = min(machines.items(), key=lambda item: item[1]["clearance_m"])
        lines.append(f"least clearance to the neighbour: {pair} " + (
            f"{least['clearance_m']:.2f} m @ {least['time_s']:.1f} s" if least["clearance_m"] < watch else f">= {watch:.2f} m"))
    return "\n".join(lines)


def contact_line(contact: dict) -> str:
    """A collision: which bodies, when, how deep."""
    until = "the run's end" if contact["end_s"] is None else f"{contact['end_s']:.1f} s"
    first, second = contact["bodies"]
    return (f"collision: the {first} met the {second} at {contact['time_s']:.1f} s, {contact['depth_m']:.2f} m deep "
            f"at {contact['depth_time_s']:.1f} s, until {until}")


def fault_line(fault: dict) -> str:
    """A scheduled fault and the largest errors during and after it (bwr_twin.sim.fault_report)."""
    what = fault["kind"] + "".join(f" {fault[k]}" for k in ("axis", "scanner") if k in fault)
    if fault["end_s"] is None:
        return f"fault {what} from {fault['start_s']:g} s: never acted, the run ended first"

    def errors(window: dict | None) -> str:
        if window is None or None in window.values():
            return "none (no sample)"
        return ", ".join(f"{key.partition('_')[0]} {value:.4g} {key.partition('_')[2]}" for key, value in window.items())

    return (f"fault {what} {fault['start_s']:g}-{fault['end_s']:g} s: largest errors during {errors(fault['error_max_during'])}; "
            f"after {errors(fault['error_max_after'])}")


def plan_line(reclaim: dict) -> str:
    """How a bench plan was carried out: the rate in steady cutting against its target, the
    landing, the over-cut and the tonnes of each bench.

    `steady_within_10pct` is a fraction (0-1) of the steady cutting time, whatever its name says:
    the line gives it as such, and as a percentage."""
    target, steady = reclaim["target_rate_tph"], reclaim["steady_time_s"]
    if steady > 0:
        mean, cv = reclaim["steady_rate_mean_tph"], reclaim["steady_rate_cv"]
        within, off = reclaim["steady_within_10pct"], 100 * (mean / target - 1)
        rate = (f"steady cutting {steady:.0f} s at a mean {mean:.0f} t/h ({abs(off):.1f} % "
                f"{'below' if off < 0 else 'above'} the {target:.0f} t/h target), "
                f"steady reclaim rate CV (std/mean) {'n/a' if cv is None else f'{cv:.3f}'}, "
                f"within ±10 % of the target for {within:.2f} of the steady cutting time ({100 * within:.0f} %)")
    else:
        rate = f"no steady cutting (target {target:.0f} t/h)"
    landing = reclaim["landing_error_m"]
    benches = ", ".join(f"{t:.0f}" for t in reclaim["bench_t"])
    planned = ", ".join(f"{t:.0f}" for t in reclaim["bench_planned_t"])
    return (f"{rate}; landing error {landing:.3f} m; over-cut up to {reclaim['overcut_max_m']:.2f} m; "
            f"bench tonnes {benches} t (planned {planned} t)" if landing is not None
            else f"{rate}; the wheel never met the pile")


def _largest(axis_metrics: dict, j: int, kind: str, per: str) -> str:
    """'+0.01812 m @ 204.1 s': the largest error of one kind, in engineering units, and its time."""
    value, time = axis_metrics[f"{kind}_error_max"], axis_metrics[f"{kind}_error_max_time"]
    return f"{to_display(j, value):+.4g} {UNITS[j]}{per} @ {time:5.1f} s"
