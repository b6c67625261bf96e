"""The stockpiled material's numbers, from the scene: its bulk density and angle of repose."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bwr_twin.config.sections import StockpileSection
from bwr_twin.errors import SceneError
from bwr_twin.units import KG_PER_T


@dataclass(frozen=True)
class Material:
    """One loose material, the same through the whole pile: uniform bulk density, so tonnes are
    volume x density everywhere, and one angle of repose."""

    bulk_density: float  # kg/m^3
    angle_of_repose: float  # deg

    @classmethod
    def of(cls, section: StockpileSection, scene_path: Path) -> Material:
        """The material of a scene's [stockpile]: its `bulk_density` and its windrow's
        `angle_of_repose` (a surveyed pile gives none: SceneError)."""
        if section.windrow is None:
            raise SceneError(f"{scene_path}: [stockpile] gives no angle_of_repose (only [stockpile.windrow] "
                             "holds one): the pile cannot slump without it")
        return cls(section.bulk_density, section.windrow.angle_of_repose)

    def tonnes(self, volume: float) -> float:
        """t in `volume` m^3."""
        return volume * self.bulk_density / KG_PER_T

    def volume(self, tonnes: float) -> float:
        """m^3 of `tonnes` t."""
        return tonnes * KG_PER_T / self.bulk_density
