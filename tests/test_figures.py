"""A run's and a comparison's figures as a reader sees them: every title inside its figure, the
paper's figure numbers and frame 0 on the paper's machine only, via-point numbers that do not
print over each other, a name for every line, and a comparison's drive forces as one band per
controller over its seeds.

The runs are short: 20 s of the paper's path (PID and fuzzy, two seeds each) and the small
bench reclaim of tests/test_reclaim_plan.py on the heavy machine (90 s).
"""

from __future__ import annotations

from itertools import combinations
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import HEAVY_MJCF, PAPER_MJCF, PAPER_VIA_POINTS, SCENES, SHORT_VIA_POINTS, VARIANT_MJCF
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.text import Annotation
from test_reclaim_plan import small_scene

from bwr_twin.compare.report import binned, comparison_figures
from bwr_twin.config.scene import load_scene
from bwr_twin.results.layout import fit_titles
from bwr_twin.results.plots import is_papers_machine, number_points, run_figures
from bwr_twin.sim.lockstep import simulate, simulate_grouped

CONTROLLERS = ("pid_paper", "paper_individual_gains")


@pytest.fixture(scope="module")
def paper_runs():
    """{controller: [seed 1, seed 2]}: 20 s of the paper's path on the paper's machine."""
    scenes = [load_scene(SCENES / f"{name}.toml", {"path.via_points": SHORT_VIA_POINTS, "simulation.seed": s})
              for name in CONTROLLERS for s in (1, 2)]
    results = simulate_grouped(scenes)
    return {name: results[2 * k : 2 * k + 2] for k, name in enumerate(CONTROLLERS)}


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    """A bench reclaim of the heavy machine: a stockpile, a plan's via points, a long PID label."""
    return simulate(small_scene(tmp_path_factory.mktemp("bench")))


@pytest.fixture(scope="module")
def figures(paper_runs, bench_run):
    """{(case, file name): figure, drawn}: every figure of the three kinds of output."""
    cases = {"pid": dict(run_figures(paper_runs["pid_paper"][0])),
             "fuzzy": dict(run_figures(paper_runs["paper_individual_gains"][0])),
             "bench": dict(run_figures(bench_run)),
             "compare": dict(comparison_figures(list(CONTROLLERS), list(paper_runs.values())))}
    drawn = {(case, name): fig for case, named in cases.items() for name, fig in named.items()}
    for fig in drawn.values():
        fig.draw_without_rendering()
    return drawn


def titles(fig: Figure):
    return [t for t in [*fig.texts, *(ax.title for ax in fig.axes)] if t.get_text()]


def every_text(fig: Figure) -> str:
    """Every title and axis label of fig, one a line."""
    labels = [t.get_text() for t in titles(fig)]
    labels += [label for ax in fig.axes for label in (ax.get_xlabel(), ax.get_ylabel())]
    return "\n".join(labels)


def inside(box, fig: Figure) -> bool:
    return box.x0 >= 0 and box.y0 >= 0 and box.x1 <= fig.bbox.width and box.y1 <= fig.bbox.height


# -- titles ----------------------------------------------------------------------------------


def test_every_title_lies_inside_its_figure(figures):
    assert {"pid", "fuzzy", "bench", "compare"} == {case for case, _ in figures}
    assert len(figures["bench", "reclaim.png"].texts[0].get_text()) > 150  # the heavy PID's gains: long
    for (case, name), fig in figures.items():
        for text in titles(fig):
            assert inside(text.get_window_extent(), fig), (case, name, text.get_text())


def test_a_title_breaks_at_its_commas_and_a_word_too_wide_shrinks():
    fig = Figure(figsize=(4, 3), layout="constrained")
    fig.subplots().set_title("axes title, " * 8)
    fig.suptitle("A figure\n" + ", ".join(f"gain {k} 1.234e+06/5.678e+08" for k in range(6)))
    fit_titles(fig)
    fig.draw_without_rendering()
    lines = fig.texts[0].get_text().split("\n")
    assert lines[0] == "A figure" and len(lines) > 2 and all(line.startswith("gain") for line in lines[1:])
    assert all(inside(t.get_window_extent(), fig) for t in titles(fig))

    word = Figure(figsize=(4, 3), layout="constrained")
    word.suptitle("x" * 120)
    fit_titles(word)
    word.draw_without_rendering()
    assert word.texts[0].get_fontsize() < 12 and inside(word.texts[0].get_window_extent(), word)


# -- the paper's machine and any other --------------------------------------------------------


def test_only_the_papers_machine_cites_the_papers_figures_and_frame(figures):
    pid, fuzzy = {n: f for (c, n), f in figures.items() if c == "pid"}, {n: f for (c, n), f in figures.items()
                                                                        if c == "fuzzy"}
    assert "(paper Fig. 6, 12)" in pid["positions.png"].texts[0].get_text()
    assert "(paper Fig. 10, 13 left)" in pid["errors_position.png"].texts[0].get_text()
    assert "(paper Fig. 9)" in fuzzy["fuzzy_outputs.png"].texts[0].get_text()
    assert "the paper's frame 0" in every_text(pid["cp_path.png"]) and "z_p, along the rail" in every_text(
        pid["cp_path.png"])
    for (case, name), fig in figures.items():
        if case == "bench":
            assert "paper" not in every_text(fig), name
    cp = every_text(figures["bench", "cp_path.png"])
    assert "rail frame: x lateral, y down, z along the rail" in cp and "z, along the rail [m]" in cp


def test_the_papers_machine_is_the_shipped_file_byte_for_byte_without_payloads(tmp_path):
    copy, edited = tmp_path / "copy" / "bwr.xml", tmp_path / "edited" / "bwr.xml"
    for path in (copy, edited):
        path.parent.mkdir()
    copy.write_bytes(PAPER_MJCF.read_bytes())
    edited.write_bytes(PAPER_MJCF.read_bytes() + b"\n")

    def machine(path, payloads=()):
        return SimpleNamespace(path=path, payloads=payloads)

    assert is_papers_machine(machine(PAPER_MJCF)) and is_papers_machine(machine(copy))
    for other in (edited, HEAVY_MJCF, VARIANT_MJCF, tmp_path / "missing.xml"):
        assert not is_papers_machine(machine(other)), other
    assert not is_papers_machine(machine(PAPER_MJCF, payloads=("ore on the wheel",)))


# -- via-point numbers ------------------------------------------------------------------------


def labels_overlap(fig: Figure) -> list[tuple[str, str]]:
    pairs = []
    for ax in fig.axes:
        boxes = [(a.get_text(), a.get_window_extent()) for a in ax.texts if isinstance(a, Annotation)]
        pairs += [(a, b) for (a, box_a), (b, box_b) in combinations(boxes, 2) if box_a.overlaps(box_b)]
    return pairs


def test_the_via_points_of_a_bench_reclaim_are_numbered_without_overlap(figures, bench_run):
    fig = figures["bench", "cp_path.png"]
    assert len(bench_run.trajectory.times) > 5 and all(ax.texts for ax in fig.axes)
    assert labels_overlap(fig) == []


def test_crowded_via_points_keep_only_labels_that_fit_and_coinciding_ones_share_one():
    fig = Figure(figsize=(6, 4), layout="constrained")
    ax = fig.subplots()
    paper = np.array([(p[2], p[0]) for _, p in PAPER_VIA_POINTS])  # plan view: the path ends where it began
    crowd = np.column_stack([np.linspace(0.0, 20.0, 21), np.full(21, -30.0)])  # 1 m apart: a few pixels
    ax.plot(*paper.T, "rs")
    ax.plot(*crowd.T, "bs")
    ax.set_xlim(-10, 70)
    ax.set_ylim(-60, 10)
    fig.draw_without_rendering()
    assert [label.get_text() for label in number_points(ax, paper)] == ["1, 5", "2", "3", "4"]
    crowded = [label.get_text() for label in number_points(ax, crowd)]
    assert crowded[0] == "1" and 1 < len(crowded) < 21
    numbers = [n for label in crowded for n in label.split(", ")]
    assert len(numbers) == len(set(numbers))
    fig.draw_without_rendering()
    assert labels_overlap(fig) == []


# -- every line named -------------------------------------------------------------------------


def test_every_line_has_a_legend_entry_or_is_alone_under_its_axis_label(figures):
    for (case, name), fig in figures.items():
        legends = {t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()}
        for ax in fig.axes:
            for line in ax.lines:
                label = line.get_label()
                alone = len(ax.lines) == 1 and label.lower() in ax.get_ylabel().lower()
                assert not label.startswith("_") and (label in legends or alone), (case, name, label)


def test_via_point_times_are_named_in_the_legend(figures):
    legend = figures["bench", "positions.png"].axes[0].get_legend()
    assert [t.get_text() for t in legend.get_texts()].count("via point times") == 1


# -- a comparison's drive forces --------------------------------------------------------------


def test_compared_drive_forces_are_one_translucent_band_and_mean_per_controller(figures, paper_runs):
    fig = figures["compare", "drive_forces.png"]
    for ax in fig.axes:
        bands = [c for c in ax.collections if isinstance(c, PolyCollection)]
        assert len(bands) == len(CONTROLLERS) and len(ax.lines) == len(CONTROLLERS)
        assert all(band.get_facecolor()[0][3] < 0.5 for band in bands)  # the bands beneath show through
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == list(CONTROLLERS)
    # Every seed's every sample lies within its controller's band.
    for band, runs in zip(fig.axes[1].collections, paper_runs.values()):
        bounds = np.concatenate([path.vertices[:, 1] for path in band.get_paths()])
        assert np.isfinite(bounds).all() and len(band.get_paths()) == 1  # no bin without samples
        lower, upper = bounds.min(), bounds.max()
        forces = np.concatenate([r.drive_force[:, 1] / 1e3 for r in runs])
        assert lower == pytest.approx(forces.min()) and upper == pytest.approx(forces.max())


def test_binned_range_and_mean_equal_a_loop_over_the_bins():
    rng = np.random.default_rng(7)
    times = [np.sort(rng.uniform(0.0, 10.0, n)) for n in (50, 80)]
    values = [rng.normal(size=len(t)) for t in times]
    edges = np.linspace(0.0, 12.0, 13)  # the last two bins hold no sample
    low, high, mean = binned(times, values, edges)
    t, v = np.concatenate(times), np.concatenate(values)
    for i in range(len(edges) - 1):
        in_bin = v[(t >= edges[i]) & (t < edges[i + 1])]
        if len(in_bin):
            assert (low[i], high[i]) == (in_bin.min(), in_bin.max())
            assert mean[i] == pytest.approx(in_bin.mean(), rel=1e-12)
        else:
            assert np.isnan(low[i]) and np.isnan(high[i]) and np.isnan(mean[i])
