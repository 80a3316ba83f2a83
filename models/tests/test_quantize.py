"""Int8 quantisation keeps the model readable by the daemon and close to its float32 source."""

import numpy as np
import onnx
import onnxruntime as ort

from phyllo_train.encoders import load_pretrained
from phyllo_train.export import export_onnx
from phyllo_train.model import build_model
from phyllo_train.tools.quantize import calibration_inputs, quantize


def test_encoder_only_int8_keeps_metadata_and_outputs(tmp_path, contract, tiny_dataset):
    model = build_model(contract.num_classes, seed=0, encoder="efficientnet-lite0")
    load_pretrained(model.encoder)
    src = export_onnx(model, tmp_path / "f32.onnx", contract, model_name="t", trained=False, training_data="none")
    inputs = calibration_inputs(tiny_dataset, 2, 256)
    assert len(inputs) == 2 and inputs[0].shape == (1, 3, 256, 256)
    out = tmp_path / "int8.onnx"
    quantize(src, out, inputs, encoder_only=True)
    assert out.stat().st_size < 0.6 * src.stat().st_size
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    source_meta = {p.key: p.value for p in onnx.load(str(src)).metadata_props}
    assert {k: meta[k] for k in source_meta} == source_meta
    assert meta["phyllo.quantized"].startswith("int8 QDQ per-channel, encoder")
    graph = onnx.load(str(out)).graph
    quantized = {n.name for n in graph.node if n.op_type == "DequantizeLinear"}
    assert quantized and not any("head" in n for n in quantized)
    runs = [ort.InferenceSession(str(p), providers=["CPUExecutionProvider"]) for p in (src, out)]
    a, b = (s.run(["semantic"], {"image": inputs[0]})[0].ravel() for s in runs)
    assert np.corrcoef(a, b)[0, 1] > 0.95


def test_frames_calibrate_on_the_pipelines_tiles_and_the_daemon_keys_survive(tmp_path, tiny_dataset):
    from pathlib import Path

    from phyllo_train.tools.quantize import main, pipeline_tiles

    src = Path(__file__).resolve().parents[1] / "phyllo-untrained.onnx"
    frames = sorted((tiny_dataset / "images").glob("*.png"))
    tiles = pipeline_tiles(src, frames, limit=3)
    assert len(tiles) == 3 and all(t.shape == (1, 3, 512, 512) and t.dtype == np.float32 for t in tiles)
    # The tiles are normalised as the daemon feeds them: not raw pixels.
    assert -3 < min(float(t.min()) for t in tiles) < 0 < max(float(t.max()) for t in tiles) < 3
    out = tmp_path / "int8.onnx"
    main([str(src), "--out", str(out), "--frames", str(tiny_dataset / "images"), "--tiles", "2"])
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert meta["phyllo.contract_version"] == "1"
    assert meta["phyllo.quantized"] == "int8 QDQ per-channel, all, 2 calibration tiles cut from 6 frames of tiny0"
    runs = [ort.InferenceSession(str(p), providers=["CPUExecutionProvider"]) for p in (src, out)]
    a, b = (s.run(["semantic"], {"image": tiles[0]})[0] for s in runs)
    assert a.shape == b.shape and np.isfinite(b).all()
