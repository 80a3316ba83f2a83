"""Commands around training that are still in use, outside the training path itself.

``from_onnx`` (a checkpoint back from a shipped ONNX file; ``scripts/device-prepare.sh``),
``resume_state`` (resume points to commit; ``scripts/tip-schedule.sh``), ``truth_rules``
(counts under other truth rules; ``scripts/tip-schedule.sh score``), ``tips`` and ``tip_cache``
(the leaf-tip head on frozen features and its export; the test fixture
``phyllo-tips-untrained.onnx``), ``postprocess`` (the Python twin of the Rust decoder) and
``bench`` (ONNX Runtime latency per tile).
"""
