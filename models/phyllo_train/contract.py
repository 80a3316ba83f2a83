"""Run-time view of ``models/contract.toml`` (the label and model contract).

The Rust crate ``phyllo-contract`` embeds the same file at compile time; this
module only reads it, so the trainer can never drift from the daemon.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

#: Default location: ``models/contract.toml`` next to this package.
DEFAULT_CONTRACT_PATH = Path(__file__).resolve().parent.parent / "contract.toml"


@dataclass(frozen=True)
class Contract:
    """Typed subset of the contract that training and export need."""

    version: int
    class_names: tuple[str, ...]
    things: tuple[int, ...]
    leaf: int
    label_divisor: int
    max_instances: int
    input_name: str
    tile: int
    mean: tuple[float, float, float]
    std: tuple[float, float, float]
    frame_height: int
    crop_scale: float
    tile_overlap: int
    zoom_plant_height: int
    max_zoom: float
    stride: int
    semantic_name: str
    center_name: str
    offset_name: str
    center_sigma: float
    tip_name: str
    tip_sigma: float
    meta_contract_version: str
    meta_model_name: str
    meta_trained: str
    meta_training_data: str
    raw: dict

    @property
    def num_classes(self) -> int:
        """Number of semantic classes (logit channels)."""
        return len(self.class_names)

    @property
    def output_names(self) -> tuple[str, str, str]:
        """ONNX output names in the order the network returns them."""
        return (self.semantic_name, self.center_name, self.offset_name)

    @property
    def output_names_with_tip(self) -> tuple[str, str, str, str]:
        """Output names of a model with the optional leaf-tip head (:mod:`phyllo_train.tools.tips`)."""
        return (*self.output_names, self.tip_name)


def _parse(raw: dict) -> Contract:
    cls, lab, inp, out, meta = (raw[k] for k in ("classes", "label", "input", "outputs", "metadata"))
    if inp["layout"] != "NCHW" or inp["dtype"] != "float32" or inp["channels"] != "RGB":
        raise ValueError(f"unsupported input spec in contract: {inp}")
    if lab["format"] != "png16":
        raise ValueError(f"unsupported label format in contract: {lab['format']}")
    return Contract(
        version=int(raw["version"]),
        class_names=tuple(cls["names"]),
        things=tuple(int(t) for t in cls["things"]),
        leaf=int(cls["leaf"]),
        label_divisor=int(lab["divisor"]),
        max_instances=int(lab["max_instances"]),
        input_name=inp["name"],
        tile=int(inp["tile"]),
        mean=tuple(float(v) for v in inp["mean"]),
        std=tuple(float(v) for v in inp["std"]),
        frame_height=int(inp["frame_height"]),
        crop_scale=float(inp["crop_scale"]),
        tile_overlap=int(inp["tile_overlap"]),
        zoom_plant_height=int(inp.get("zoom_plant_height", 0)),
        max_zoom=float(inp.get("max_zoom", 1.0)),
        stride=int(out["stride"]),
        semantic_name=out["semantic"],
        center_name=out["center"],
        offset_name=out["offset"],
        center_sigma=float(out["center_sigma"]),
        tip_name=out.get("tip", "tip"),
        tip_sigma=float(out.get("tip_sigma", 1.5)),
        meta_contract_version=meta["contract_version"],
        meta_model_name=meta["model_name"],
        meta_trained=meta["trained"],
        meta_training_data=meta["training_data"],
        raw=raw,
    )


@lru_cache(maxsize=8)
def load_contract(path: str | os.PathLike | None = None) -> Contract:
    """Load and validate the contract (``$PHYLLO_CONTRACT`` or ``models/contract.toml``)."""
    p = Path(path or os.environ.get("PHYLLO_CONTRACT") or DEFAULT_CONTRACT_PATH)
    with open(p, "rb") as f:
        return _parse(tomllib.load(f))
