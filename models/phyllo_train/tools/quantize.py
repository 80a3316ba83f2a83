"""Int8 quantisation of an exported model with ONNX Runtime (static, QDQ, per-channel weights).

    python -m phyllo_train.tools.quantize models/phyllo.onnx --out out/int8/phyllo-int8.onnx \
        --frames /work/data/int8-calib-s700901/images [--tiles 64]
    python -m phyllo_train.tools.quantize phyllo-e40.onnx --out /tmp/e40-int8.onnx \
        --calibrate /work/data/train-e40 --images 24 [--encoder-only]

Activations are calibrated on synthetic images (never an evaluation set).
With ``--frames`` (what ``scripts/int8-measure.sh`` uses) the tiles are cut
from whole frames exactly as the counting pipeline cuts them
(``models/reference_pipeline.py``: plant box, scale, 512² tiles, and the
enlarged second pass of a small plant), so the ranges are those the model
meets when it counts. With ``--calibrate`` a training set's images are
resized to one tile each, as crops are. Either way a tile is RGB scaled to
[0, 1], then the contract's mean/std. ``--encoder-only`` leaves the decoder
and heads in float32, where the centre heatmap's peaks decide the count. The
metadata (name, contract, architecture) is copied, so the daemon and
``from_onnx`` read the file as they read its source; ``phyllo.quantized``
says what was done.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from ..contract import load_contract


def calibration_inputs(dataset: Path, images: int, tile: int | None = None) -> list[np.ndarray]:
    """Normalised NCHW tiles (``tile`` px, the contract's by default) from the dataset's manifest,
    spread evenly over it."""
    rows = [json.loads(line) for line in (dataset / "manifest.jsonl").read_text().splitlines() if line.strip()]
    if not rows:
        raise SystemExit(f"{dataset}/manifest.jsonl: no rows")
    c = load_contract()
    tile = tile or c.tile
    mean = np.asarray(c.mean, np.float32)[:, None, None]
    std = np.asarray(c.std, np.float32)[:, None, None]
    step = max(1, len(rows) // images)
    out = []
    for row in rows[::step][:images]:
        with Image.open(dataset / row["image"]) as im:
            x = np.asarray(im.convert("RGB").resize((tile, tile)), np.float32).transpose(2, 0, 1) / 255.0
        out.append(((x - mean) / std)[None].astype(np.float32))
    return out


def pipeline_tiles(model: Path, frames: list[Path], limit: int, seed: int = 0) -> list[np.ndarray]:
    """Normalised 1×3×512×512 tiles of ``frames`` as the counting pipeline cuts
    them, the enlarged pass of a small plant included (its zoom comes from the
    float model's first pass, as when counting); at most ``limit``, drawn
    evenly at random."""
    import onnxruntime as ort

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    import reference_pipeline as pipeline  # models/, beside the package

    sess = ort.InferenceSession(str(model), providers=["CPUExecutionProvider"])
    names = [pipeline.CONTRACT["outputs"][k] for k in ("semantic", "center", "offset")]
    tiles: list[np.ndarray] = []
    for path in frames:
        img = np.asarray(Image.open(path).convert("RGB"))
        canvas, boxes, plant, scale = pipeline.prepare(img, None)
        batch = pipeline.normalise(canvas, boxes)
        tiles.extend(batch[i:i + 1] for i in range(len(batch)))
        sem, cen, off = sess.run(names, {pipeline.CONTRACT["input"]["name"]: batch})
        _, rows = pipeline.postprocess(
            *pipeline.stitch(sem, cen, off, boxes, canvas.shape[1], canvas.shape[0]), plant, canvas
        )
        zoom = pipeline.zoom_for(rows)
        if zoom > 1.0:
            canvas, boxes, _, _ = pipeline.prepare(img, scale * zoom)
            batch = pipeline.normalise(canvas, boxes)
            tiles.extend(batch[i:i + 1] for i in range(len(batch)))
    if len(tiles) > limit:
        keep = sorted(random.Random(seed).sample(range(len(tiles)), limit))
        tiles = [tiles[i] for i in keep]
    return [t.astype(np.float32) for t in tiles]


def quantize(src: Path, out: Path, inputs: list[np.ndarray], encoder_only: bool, note: str = "") -> None:
    """Writes the int8 model of ``src`` to ``out``, calibrated on ``inputs``;
    ``note`` is appended to the ``phyllo.quantized`` metadata."""
    import onnx
    from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    class Reader(CalibrationDataReader):
        def __init__(self) -> None:
            self.items = iter(inputs)

        def get_next(self):
            x = next(self.items, None)
            return None if x is None else {"image": x}

    with tempfile.TemporaryDirectory() as tmp:
        pre = Path(tmp) / "pre.onnx"
        quant_pre_process(str(src), str(pre), skip_symbolic_shape=True)
        nodes = ([n.name for n in onnx.load(str(pre)).graph.node if n.name.startswith("/encoder/")]
                 if encoder_only else None)
        quantize_static(str(pre), str(out), Reader(), quant_format=QuantFormat.QDQ, per_channel=True,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8, nodes_to_quantize=nodes)
    model, source = onnx.load(str(out)), onnx.load(str(src))
    del model.metadata_props[:]
    for p in source.metadata_props:
        model.metadata_props.add(key=p.key, value=p.value)
    what = "encoder" if encoder_only else "all"
    model.metadata_props.add(
        key="phyllo.quantized", value=f"int8 QDQ per-channel, {what}, {len(inputs)} calibration tiles{note}"
    )
    onnx.save(model, str(out))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    source = ap.add_mutually_exclusive_group(required=True)
    source.add_argument("--frames", type=Path, help="folder of whole PNG frames, cut into tiles as when counting")
    source.add_argument("--calibrate", type=Path, help="phyllo-gen training set whose images calibrate, one tile each")
    ap.add_argument("--tiles", type=int, default=64, help="with --frames: calibration tiles, at most")
    ap.add_argument("--images", type=int, default=24, help="with --calibrate: images")
    ap.add_argument("--encoder-only", action="store_true", help="quantise only the encoder's nodes")
    args = ap.parse_args(argv)
    if args.frames:
        frames = sorted(args.frames.glob("*.png"))
        if not frames:
            raise SystemExit(f"{args.frames}: no PNG frames to calibrate on")
        inputs = pipeline_tiles(args.model, frames, args.tiles)
        note = f" cut from {len(frames)} frames of {args.frames.parent.name or args.frames.name}"
    else:
        inputs, note = calibration_inputs(args.calibrate, args.images), ""
    args.out.parent.mkdir(parents=True, exist_ok=True)
    quantize(args.model, args.out, inputs, args.encoder_only, note)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB, from {args.model.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
