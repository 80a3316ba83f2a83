"""Int8 quantisation of an exported model with ONNX Runtime (static, QDQ, per-channel weights).

    python -m phyllo_train.experiments.quantize phyllo-e40.onnx --out /tmp/e40-int8.onnx \
        --calibrate /work/data/train-e40 --images 24 [--encoder-only]

Activations are calibrated on training images (never an evaluation set), read
as the daemon feeds a 512² tile: RGB scaled to [0, 1], then the contract's
mean/std. ``--encoder-only`` leaves the decoder and heads in float32, where
the centre heatmap's peaks decide the count. The metadata (name, contract,
architecture) is copied, so the daemon and ``from_onnx`` read the file as
they read its source; ``phyllo.quantized`` says what was done.
"""

from __future__ import annotations

import argparse
import json
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


def quantize(src: Path, out: Path, inputs: list[np.ndarray], encoder_only: bool) -> None:
    """Writes the int8 model of ``src`` to ``out``, calibrated on ``inputs``."""
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
    model.metadata_props.add(key="phyllo.quantized", value=f"int8 QDQ per-channel, {what}, {len(inputs)} calibration tiles")
    onnx.save(model, str(out))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--calibrate", type=Path, required=True, help="phyllo-gen training set whose images calibrate")
    ap.add_argument("--images", type=int, default=24)
    ap.add_argument("--encoder-only", action="store_true", help="quantise only the encoder's nodes")
    args = ap.parse_args()
    inputs = calibration_inputs(args.calibrate, args.images)
    quantize(args.model, args.out, inputs, args.encoder_only)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.1f} MB)")


if __name__ == "__main__":
    main()
