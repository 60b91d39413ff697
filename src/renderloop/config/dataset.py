"""The settings of a training set (`renderloop dataset`): what its images are drawn from.

Like `TrainSettings` they are not part of a run's `Config` (a dataset is many greenhouses, each drawn from the seed
and the scene's index by `renderloop.dataset.scenes`), but are bounded the same way: a value out of its range is
one line naming the field. The settings are the dataset's manifest (`dataset.json`), so a dataset grows only with
the settings it was made with; the image count is not one of them.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from renderloop.config.fields import Count, Fraction, Real, Strict, checked

STYLES = ("simple", "pepper", "highwire")  # plants.style
ENVIRONMENTS = ("plain", "film")  # greenhouse.environment.kind
DISTANCE = (0.3, 1.2)  # m from the plant's axis, horizontal
MAX_DISTANCE = 10.0  # m: a view farther than this from a plant sees the whole room, not the plant
Distance = Real(0.0, MAX_DISTANCE, low_open=True)


def _once(name: str, chosen: tuple[str, ...]) -> None:
    if len(set(chosen)) != len(chosen):
        raise ValueError(f"{name}: {', '.join(chosen)}: choose each once")


class DatasetSpec(Strict):
    """What defines the images of a dataset (its manifest); the image count is not part of it."""

    seed: Count(0, 2**63 - 1) = Field(0, description="Seed of the scenes and views, 0 to 2^63-1.")
    width: Count(16, 4096) = Field(320, description="Image width, px, 16 to 4096 (`renderloop dataset` makes the height "
                                   "3/4 of it).")
    height: Count(12, 3072) = Field(240, description="Image height, px, 12 to 3072.")
    views_per_scene: Count(1, 1000) = Field(16, description="Views rendered from each random scene, 1 to 1000.")
    samples: tuple[Count(1, 65536), ...] = Field(
        (2, 4, 8), min_length=1, max_length=64,
        description="Cycles samples per pixel a scene draws from, equally, each 1 to 65536 (1 to 64 choices): path-"
        "tracing noise levels around the run's default, after denoising.")
    val_every: Count(2, 1_000_000) = Field(10, description="Every n-th scene is held out for validation, n from 2 to "
                                           "1 000 000.")
    distance: tuple[Distance, Distance] = Field(
        DISTANCE, description=f"Near and far camera distance from the plant's axis, m, each above 0 and at most "
        f"{MAX_DISTANCE:g}, near not beyond far.")
    sensor: Fraction = Field(0.0, description="Share of the views through the colour-sensor model (exposure, white "
                             "balance, noise, vignetting, defocus, sharpening, JPEG), 0 to 1.")
    styles: tuple[Literal[STYLES], ...] = Field(
        ("simple",), min_length=1, description="Plant styles (plants.style) a scene draws from, equally: one or more of "
        f"{', '.join(STYLES)}, each once.")
    environments: tuple[Literal[ENVIRONMENTS], ...] = Field(
        ("plain",), min_length=1, description="Surroundings (greenhouse.environment.kind) a scene draws from, equally: "
        f"one or more of {', '.join(ENVIRONMENTS)}, each once.")
    clutter: bool = Field(False, description="Things that are not peppers in every scene: fruit-like shapes, cans, "
                          "cartons, patterned mats and boards.")
    close: Fraction = Field(0.0, description="Share of the views of one fruit from 0.12-0.5 m, 0 to 1.")
    picked: Fraction = Field(0.0, description="Share of the scenes with crates and loose picked fruit, labelled, 0 to 1; "
                             "half their close views look at one.")

    @model_validator(mode="after")
    def _choices(self) -> DatasetSpec:
        if self.distance[0] > self.distance[1]:
            raise ValueError(f"distance: near {self.distance[0]:g} m is beyond far {self.distance[1]:g} m")
        _once("styles", self.styles)
        _once("environments", self.environments)
        return self

    @classmethod
    def of(cls, **values: Any) -> DatasetSpec:
        """The spec of `values` over the defaults, or the one-line UserError naming the field: `dataset: field: problem`."""
        return checked(cls, "dataset", **values)

    def is_val(self, scene_index: int) -> bool:
        return scene_index % self.val_every == self.val_every - 1
