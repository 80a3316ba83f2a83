"""Images as the daemon sees them: the reference pipeline's tiling, and image lists from folders or datasets."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

from ..dataset import read_manifest

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".tif", ".tiff"}


@functools.cache
def reference_pipeline():
    """models/reference_pipeline.py, the Python twin of the daemon's tiling (a script, not a package module)."""
    path = Path(__file__).resolve().parents[2] / "reference_pipeline.py"
    spec = importlib.util.spec_from_file_location("phyllo_reference_pipeline", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def image_paths(sources: list[Path]) -> list[Path]:
    """Image files named by ``sources``: files, folders of images, or phyllo-gen datasets (all splits)."""
    paths: list[Path] = []
    for src in sources:
        if src.is_file():
            paths.append(src)
        elif (src / "manifest.jsonl").exists():
            paths += [src / row["image"] for row in read_manifest(src)]
        elif src.is_dir():
            paths += sorted(p for p in src.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        else:
            raise FileNotFoundError(f"{src}: no such file or folder")
    return paths
