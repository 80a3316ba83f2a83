"""The photometric augmentation applied on the training device, one batch at a time.

Loader processes spend about half of each sample on colour, blur, noise and
JPEG (EXPERIMENTS.md, "The first GPU run"); on a GPU those are cheap batched
tensor ops. The loader draws each sample's :class:`~phyllo_train.augment.PhotometricDraw`
as before and sends the crop as rendered, with the draw and its plant mask;
:func:`apply_batch` repeats :func:`~phyllo_train.augment.apply_photometric`
op for op. Two ops differ in detail: hue and saturation are shifted in float
HSV (the CPU path goes through PIL's 8-bit HSV), and JPEG is a block-DCT
quantisation with libjpeg's tables and 4:2:0 chroma (bilinear chroma
upsampling where libjpeg uses its triangle filter).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from ..augment import LUMA, PhotometricDraw
from ..contract import Contract

# Columns of PhotometricDraw.to_vector().
(_BACKLIGHT, _BL_GAIN, _BL_DESAT, _HSV, _HUE, _SAT, _WB_R, _WB_G, _WB_B, _BRIGHT, _CONTRAST, _GRAD_ANGLE,
 _GRAD, _GAMMA, _FR_RY, _FR_RX, _FR_BY, _FR_BX, _BLUR, _NOISE, _NOISE_SEED, _JPEG) = range(PhotometricDraw.FIELDS)

# ITU T.81 Annex K tables, the base that libjpeg (and so PIL) scales by quality.
_Q_LUMA = [16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
           14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
           49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99]
_Q_CHROMA = [17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99, 99, 99,
             47, 66, 99, 99, 99, 99, 99, 99] + [99] * 32


def jpeg_tables(quality: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, 8, 8) luma and chroma quantisation tables for qualities 1..100, as libjpeg scales them."""
    q = quality.clamp(1, 100).to(torch.float64)
    scale = torch.where(q < 50, 5000.0 / q, 200.0 - 2.0 * q)[:, None, None]

    def scaled(base: list[int]) -> torch.Tensor:
        t = torch.tensor(base, dtype=torch.float64, device=quality.device).view(1, 8, 8)
        return torch.floor((t * scale + 50.0) / 100.0).clamp(1, 255).to(torch.float32)

    return scaled(_Q_LUMA), scaled(_Q_CHROMA)


def _dct_matrix(device: torch.device) -> torch.Tensor:
    """The orthonormal 8-point DCT-II; JPEG's 2-D transform is D @ block @ D.T."""
    k = torch.arange(8, dtype=torch.float64)
    d = torch.cos((2 * k[None, :] + 1) * k[:, None] * math.pi / 16) * 0.5
    d[0] /= math.sqrt(2.0)
    return d.to(device=device, dtype=torch.float32)


def _quantise_plane(p: torch.Tensor, table: torch.Tensor, dct: torch.Tensor) -> torch.Tensor:
    """8x8 block DCT, quantise, dequantise and invert one (B, H, W) plane (H, W multiples of 8)."""
    b, h, w = p.shape
    blocks = (p - 128.0).view(b, h // 8, 8, w // 8, 8).permute(0, 1, 3, 2, 4)
    coef = dct @ blocks @ dct.T
    q = table[:, None, None]
    coef = torch.round(coef / q) * q
    out = dct.T @ coef @ dct
    return (out.permute(0, 1, 3, 2, 4).reshape(b, h, w) + 128.0).round().clamp(0, 255)


def jpeg(x: torch.Tensor, quality: torch.Tensor) -> torch.Tensor:
    """JPEG round trip of (B, 3, H, W) RGB in 0..255 at per-image ``quality``; returns 0..255 integers."""
    b, _, h, w = x.shape
    ph, pw = (-h) % 16, (-w) % 16
    if ph or pw:
        x = F.pad(x, (0, pw, 0, ph), mode="replicate")
    r, g, bl = x.unbind(1)
    y = LUMA[0] * r + LUMA[1] * g + LUMA[2] * bl
    cb = -0.168736 * r - 0.331264 * g + 0.5 * bl + 128.0
    cr = 0.5 * r - 0.418688 * g - 0.081312 * bl + 128.0
    y, cb, cr = (c.round().clamp(0, 255) for c in (y, cb, cr))
    chroma = F.avg_pool2d(torch.stack([cb, cr], 1), 2)  # 4:2:0, PIL's default
    lq, cq = jpeg_tables(quality)
    dct = _dct_matrix(x.device)
    y = _quantise_plane(y, lq, dct)
    cb2 = _quantise_plane(chroma[:, 0], cq, dct)
    cr2 = _quantise_plane(chroma[:, 1], cq, dct)
    chroma = F.interpolate(torch.stack([cb2, cr2], 1), scale_factor=2, mode="bilinear", align_corners=False)
    cb, cr = chroma[:, 0] - 128.0, chroma[:, 1] - 128.0
    rgb = torch.stack([y + 1.402 * cr, y - 0.344136 * cb - 0.714136 * cr, y + 1.772 * cb], 1)
    return rgb.round().clamp(0, 255)[:, :, :h, :w]


def _rgb_to_hsv(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(B, 3, H, W) RGB in [0, 1] -> hue in [0, 1), saturation, value, each (B, H, W)."""
    r, g, b = x.unbind(1)
    v, arg = x.max(1)
    c = v - x.min(1).values
    s = torch.where(v > 0, c / v.clamp_min(1e-12), torch.zeros_like(v))
    cs = c.clamp_min(1e-12)
    h = torch.where(arg == 0, ((g - b) / cs) % 6, torch.where(arg == 1, (b - r) / cs + 2, (r - g) / cs + 4))
    h = torch.where(c > 0, h / 6.0, torch.zeros_like(h))
    return h, s, v


def _hsv_to_rgb(h: torch.Tensor, s: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`_rgb_to_hsv`."""
    k = torch.stack([(5 + 6 * h) % 6, (3 + 6 * h) % 6, (1 + 6 * h) % 6], 1)
    m = torch.minimum(k, 4 - k).clamp(0, 1)
    return v[:, None] - v[:, None] * s[:, None] * m


def _box3(m: torch.Tensor) -> torch.Tensor:
    """3x3 mean with edge padding of (B, 1, H, W), as augment.backlight softens its mask."""
    return F.avg_pool2d(F.pad(m, (1, 1, 1, 1), mode="replicate"), 3, stride=1)


def _blur(x: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
    """Separable Gaussian blur of (B, 3, H, W) with per-image sigma (0 = unchanged), edges replicated."""
    b, c, h, w = x.shape
    radius = max(1, math.ceil(3 * float(sigma.max())))
    t = torch.arange(-radius, radius + 1, device=x.device, dtype=torch.float32)
    s = sigma.clamp_min(1e-3)[:, None].to(torch.float32)
    k = torch.exp(-0.5 * (t[None] / s) ** 2)
    k = k / k.sum(1, keepdim=True)
    k = k.repeat_interleave(c, 0)  # (B*3, K): one kernel per image plane
    planes = F.pad(x.reshape(1, b * c, h, w), (radius, radius, radius, radius), mode="replicate")
    planes = F.conv2d(planes, k[:, None, None, :], groups=b * c)
    planes = F.conv2d(planes, k[:, None, :, None], groups=b * c)
    return planes.reshape(b, c, h, w)


def apply_batch(rgb: torch.Tensor, draws: torch.Tensor, plant: torch.Tensor) -> torch.Tensor:
    """Applies each row of ``draws`` ((B, FIELDS), ``PhotometricDraw.to_vector``) to its image.

    ``rgb``: (B, 3, H, W) uint8 crops as rendered; ``plant``: (B, H, W) bool masks.
    Returns float32 (B, 3, H, W) in 0..255 holding integers, as the CPU path's uint8.
    """
    p = draws.to(device=rgb.device, dtype=torch.float32)
    b, _, h, w = rgb.shape

    def col(i: int) -> torch.Tensor:
        return p[:, i].view(b, 1, 1, 1)

    x = rgb.to(torch.float32) / 255.0
    if bool((p[:, _BACKLIGHT] > 0).any()):
        soft = _box3(plant[:, None].to(torch.float32)) * col(_BACKLIGHT)
        lum = sum(wt * x[:, i:i + 1] for i, wt in enumerate(LUMA))
        dark = (lum + (x - lum) * (1.0 - col(_BL_DESAT))) * col(_BL_GAIN)
        x = x + (dark - x) * soft
    if bool((p[:, _HSV] > 0).any()):
        hh, ss, vv = _rgb_to_hsv(x.clamp(0, 1))
        hh = (hh + p[:, _HUE].view(b, 1, 1)) % 1.0
        ss = (ss * p[:, _SAT].view(b, 1, 1)).clamp(0, 1)
        x = torch.where(col(_HSV) > 0, _hsv_to_rgb(hh, ss, vv), x)
    x = x * p[:, _WB_R:_WB_B + 1].view(b, 3, 1, 1) * col(_BRIGHT)
    m = x.mean((1, 2, 3), keepdim=True)
    x = (x - m) * col(_CONTRAST) + m
    yy = (torch.arange(h, device=x.device, dtype=torch.float32) / h - 0.5).view(1, 1, h, 1)
    xx = (torch.arange(w, device=x.device, dtype=torch.float32) / w - 0.5).view(1, 1, 1, w)
    a = col(_GRAD_ANGLE)
    x = x * (1.0 + (torch.cos(a) * yy + torch.sin(a) * xx) * col(_GRAD))
    x = x.clamp(0.0, 1.0) ** col(_GAMMA)
    shifts = p[:, _FR_RY:_FR_BX + 1].round().to(torch.int64).tolist()
    if any(any(s) for s in shifts):
        planes = []
        for i, (ry, rx, by, bx) in enumerate(shifts):
            planes.append(torch.stack([torch.roll(x[i, 0], (ry, rx), (0, 1)), x[i, 1],
                                       torch.roll(x[i, 2], (by, bx), (0, 1))]))
        x = torch.stack(planes)
    x = torch.floor(x * 255.0 + 0.5)
    blur = p[:, _BLUR]
    if bool((blur > 0).any()):
        x = torch.where(col(_BLUR) > 0, _blur(x, blur).round(), x)
    noise = p[:, _NOISE].tolist()
    seeds = p[:, _NOISE_SEED].round().to(torch.int64).tolist()
    if any(s > 0 for s in noise):
        gen = torch.Generator(device=x.device)
        field = torch.zeros_like(x)
        for i, (sigma, seed) in enumerate(zip(noise, seeds)):
            if sigma > 0:
                gen.manual_seed(seed)
                field[i] = torch.randn(x.shape[1:], generator=gen, device=x.device) * sigma
        x = torch.floor((x + field).clamp(0, 255))
    quality = p[:, _JPEG]
    if bool((quality > 0).any()):
        x = torch.where(col(_JPEG) > 0, jpeg(x, quality), x)
    return x


def finish_batch(xs: torch.Tensor, ts: dict[str, torch.Tensor], contract: Contract) -> torch.Tensor:
    """A batch from a loader that left the photometric ops to the device: applies them
    (removing ``photometric`` and ``plant`` from ``ts``) and normalises as the contract says."""
    x = apply_batch(xs, ts.pop("photometric"), ts.pop("plant")) / 255.0
    mean = torch.tensor(contract.mean, device=x.device, dtype=torch.float32).view(1, 3, 1, 1)
    std = torch.tensor(contract.std, device=x.device, dtype=torch.float32).view(1, 3, 1, 1)
    return (x - mean) / std
