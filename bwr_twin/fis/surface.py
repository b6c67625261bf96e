"""The picture of a fuzzy system, as MATLAB's gensurf and plotmf draw it: the control surface over
the (one or two) inputs, and every variable's membership functions.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bwr_twin.fis.inference import DEFAULT_POINTS, evaluate, memberships
from bwr_twin.fis.system import FuzzySystem

DEFAULT_GRID = 31  # samples per input; gensurf's default is 15, finer shows the kinks of min/max
MAX_INPUTS = 2


def surface_figure(
    system: FuzzySystem, *, output: int = 1, grid: int = DEFAULT_GRID, points: int = DEFAULT_POINTS
) -> Figure:
    """A Figure (Agg canvas) with the surface of output `output` (1-based) and the sets.

    Two inputs: a 3-D surface and a colour map over the input ranges; one input: a curve. More
    than two inputs, or an output that does not exist, is a SceneError.
    """
    n_inputs = len(system.inputs)
    if n_inputs > MAX_INPUTS:
        raise system.fail(
            "NumInputs", f"{n_inputs} inputs: a control surface plots 1 or 2 inputs (at most {MAX_INPUTS})"
        )
    if not 1 <= output <= len(system.outputs):
        raise system.fail("NumOutputs", f"output {output} does not exist (outputs 1..{len(system.outputs)})")
    if grid < 2:
        raise ValueError(f"grid must be 2 or more samples per input, got {grid}")
    target = system.outputs[output - 1]
    variables = list(system.inputs) + list(system.outputs)
    mf_rows = (len(variables) + 1) // 2
    fig = Figure(figsize=(11.0, 4.8 + 2.4 * mf_rows), layout="constrained")
    FigureCanvasAgg(fig)
    layout = fig.add_gridspec(1 + mf_rows, 2, height_ratios=[2.0] + [1.0] * mf_rows)
    fig.suptitle(
        f"{system.name}: {target.name} ({system.and_method}/{system.or_method}/"
        f"{system.imp_method}/{system.agg_method}/{system.defuzz_method}, {points} output samples)"
    )

    axes = [np.linspace(*variable.range, grid) for variable in system.inputs]
    if n_inputs == 2:
        x1, x2 = np.meshgrid(axes[0], axes[1], indexing="ij")
        z = evaluate(system, np.column_stack([x1.ravel(), x2.ravel()]), points=points)[:, output - 1]
        z = z.reshape(x1.shape)
        ax3d = fig.add_subplot(layout[0, 0], projection="3d")
        ax3d.plot_surface(x1, x2, z, cmap="viridis", linewidth=0.2, edgecolor="k", antialiased=True)
        ax3d.set_xlabel(system.inputs[0].name)
        ax3d.set_ylabel(system.inputs[1].name)
        ax3d.set_zlabel(target.name)
        ax_map = fig.add_subplot(layout[0, 1])
        mesh = ax_map.pcolormesh(x1, x2, z, cmap="viridis", shading="gouraud")
        ax_map.set_xlabel(system.inputs[0].name)
        ax_map.set_ylabel(system.inputs[1].name)
        fig.colorbar(mesh, ax=ax_map, label=target.name)
    else:
        z = evaluate(system, axes[0][:, None], points=points)[:, output - 1]
        ax = fig.add_subplot(layout[0, :])
        ax.plot(axes[0], z)
        ax.set_xlabel(system.inputs[0].name)
        ax.set_ylabel(target.name)
        ax.grid(True, alpha=0.3)

    for k, variable in enumerate(variables):
        kind = "input" if k < n_inputs else "output"
        ax = fig.add_subplot(layout[1 + k // 2, k % 2])
        x = np.linspace(*variable.range, 401)
        for mf, mu in zip(variable.mfs, memberships(variable, x).T):
            ax.plot(x, mu, label=mf.name)
        ax.set_title(f"{kind} {variable.name!r}", fontsize="medium")
        ax.set_ylim(-0.05, 1.05)
        ax.set_xlabel(variable.name)
        ax.set_ylabel("membership")
        ax.legend(fontsize="small", loc="best")
        ax.grid(True, alpha=0.3)
    return fig
