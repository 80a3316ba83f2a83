"""Augmentation aimed at the sim-to-real gap, applied jointly to an RGB image and its label.

Geometric ops (scale jitter around the contract scale, crop, flip) touch both
image and label; photometric ops (illumination, white balance, colour, blur,
noise, JPEG) touch the image only. All randomness comes from the caller's
``numpy.random.Generator`` so samples are reproducible.
"""

from __future__ import annotations

import argparse
import io
from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageFilter


LUMA = (0.299, 0.587, 0.114)  # Rec. 601 luma weights (also JPEG's Y)


@dataclass
class AugmentConfig:
    """Knobs of the augmentation; defaults are the training recipe."""

    crop: int | None = 256          # square crop side (input px); None = keep the full tile
    scale: tuple[float, float] = (0.8, 1.25)  # log-uniform scale jitter around the contract scale
    hflip: float = 0.5
    rot90_top: bool = True          # top views have no "up": rotate by k*90 degrees
    fg_crop: float = 0.7            # probability that the crop is centred on a plant pixel
    brightness: float = 0.25        # multiplicative, +-
    contrast: float = 0.25
    saturation: float = 0.3
    hue: float = 0.03               # fraction of the hue circle
    gamma: tuple[float, float] = (0.75, 1.35)
    white_balance: float = 0.12     # per-channel gain +-
    gradient: float = 0.2           # linear illumination gradient amplitude
    blur_p: float = 0.3
    blur_sigma: tuple[float, float] = (0.3, 1.5)
    noise_p: float = 0.5
    noise_sigma: tuple[float, float] = (1.0, 8.0)  # in 0..255 units
    jpeg_p: float = 0.4
    jpeg_quality: tuple[int, int] = (35, 95)
    fringe_p: float = 0.3           # colour fringes: red and blue planes shifted by up to fringe_px
    fringe_px: int = 1
    backlight_p: float = 0.4        # plant darkened as when seen against the backlit wall
    backlight_gain: tuple[float, float] = (0.3, 0.8)   # multiplier on plant pixels
    backlight_desaturate: float = 0.5                  # up to this much of the chroma is removed

    @classmethod
    def none(cls, crop: int | None = None) -> "AugmentConfig":
        """No photometric or geometric augmentation (validation losses); optional crop size.

        The contract's small-plant zoom still applies and a window of ``crop`` (or the tile) is
        still cut from a plant larger than it, so these samples are not whole plants: never score
        counts on them against a whole label (``phyllo eval`` counts whole frames).
        """
        return cls(crop=crop, scale=(1.0, 1.0), hflip=0.0, rot90_top=False, fg_crop=0.0, brightness=0.0,
                   contrast=0.0, saturation=0.0, hue=0.0, gamma=(1.0, 1.0), white_balance=0.0,
                   gradient=0.0, blur_p=0.0, noise_p=0.0, jpeg_p=0.0, fringe_p=0.0, backlight_p=0.0)


def _scale_range(text: str) -> tuple[float, float]:
    """``--scale`` parser: ``LO,HI`` positive factors."""
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI, got {text!r}") from None
    if not 0 < lo <= hi:
        raise argparse.ArgumentTypeError(f"expected 0 < LO <= HI, got {text!r}")
    return lo, hi


def _sigma_range(text: str) -> tuple[float, float]:
    """``--noise-sigma`` parser: ``LO,HI`` in 0..255 units."""
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI, got {text!r}") from None
    if not 0 <= lo <= hi:
        raise argparse.ArgumentTypeError(f"expected 0 <= LO <= HI, got {text!r}")
    return lo, hi


def add_noise_args(ap: argparse.ArgumentParser) -> None:
    """The sensor-noise knobs a command shares with training (defaults: the recipe's)."""
    ap.add_argument("--noise-p", type=float, default=None,
                    help=f"share of training crops given Gaussian sensor noise (default {AugmentConfig.noise_p})")
    ap.add_argument("--noise-sigma", type=_sigma_range, default=None,
                    help="noise standard deviation range LO,HI in 0..255 units (default "
                         f"{AugmentConfig.noise_sigma[0]:g},{AugmentConfig.noise_sigma[1]:g})")
    ap.add_argument("--scale", type=_scale_range, default=None,
                    help="log-uniform scale jitter LO,HI around the contract scale (default "
                         f"{AugmentConfig.scale[0]:g},{AugmentConfig.scale[1]:g}); wider ranges teach a count "
                         "that does not hinge on the plant's size in the tile")


def with_noise_args(cfg: AugmentConfig, args: argparse.Namespace) -> AugmentConfig:
    """``cfg`` with the noise knobs of :func:`add_noise_args` applied where given."""
    if args.noise_p is not None:
        cfg.noise_p = args.noise_p
    if args.noise_sigma is not None:
        cfg.noise_sigma = args.noise_sigma
    if getattr(args, "scale", None) is not None:
        cfg.scale = args.scale
    return cfg


def _rescale(img: Image.Image, lab: np.ndarray, f: float) -> tuple[Image.Image, np.ndarray]:
    if abs(f - 1.0) < 1e-3:
        return img, lab
    w, h = img.size
    nw, nh = max(8, round(w * f)), max(8, round(h * f))
    img = img.resize((nw, nh), Image.BILINEAR if f > 1 else Image.BOX)
    # Nearest-neighbour on the label: instance ids must not blend.
    yi = np.minimum((np.arange(nh) + 0.5) / f, h - 1).astype(np.int64)
    xi = np.minimum((np.arange(nw) + 0.5) / f, w - 1).astype(np.int64)
    return img, lab[yi][:, xi]


# The daemon measures a plant by the rows its instances span on a first pass,
# plus a 12 px margin above and below (inference/src/zoom.rs); here the
# label's instance pixels stand in for the instances the model would find.
_BOX_MARGIN = 12
_MIN_ZOOM = 1.1  # smaller enlargements are skipped by the daemon too


def plant_rows(label: np.ndarray, label_divisor: int) -> tuple[int, int] | None:
    """Row span ``[y0, y1)`` of the label's instance pixels with margins, or None."""
    rows = np.nonzero((label % label_divisor != 0).any(1))[0]
    if len(rows) == 0:
        return None
    return int(rows[0]) - _BOX_MARGIN, int(rows[-1]) + 1 + _BOX_MARGIN


def plant_zoom(label: np.ndarray, label_divisor: int, plant_height: int, max_zoom: float) -> float:
    """The contract's enlargement for the plant in ``label`` (1.0 when none)."""
    if plant_height <= 0:
        return 1.0
    rows = plant_rows(label, label_divisor)
    if rows is None:
        return 1.0
    z = float(np.clip(plant_height / max(rows[1] - rows[0], 1), 1.0, max(max_zoom, 1.0)))
    return z if z >= _MIN_ZOOM else 1.0


def _window_around_plant(img: Image.Image, label: np.ndarray, label_divisor: int,
                         margin: int) -> tuple[Image.Image, np.ndarray, tuple[int, int]]:
    """The plant's bounding box grown by ``margin`` px, clipped to the image, and its origin (x0, y0)."""
    ys, xs = np.nonzero(label >= label_divisor)
    h, w = label.shape
    y0, y1 = max(int(ys.min()) - margin, 0), min(int(ys.max()) + 1 + margin, h)
    x0, x1 = max(int(xs.min()) - margin, 0), min(int(xs.max()) + 1 + margin, w)
    return img.crop((x0, y0, x1, y1)), label[y0:y1, x0:x1], (x0, y0)


def _pad_to(img: np.ndarray, lab: np.ndarray, size: int,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Pad to at least ``size`` per side with the edge colour (the chamber's wall) and background label.

    Also returns the (left, top) padding, by which points move.
    """
    h, w = lab.shape
    if h >= size and w >= size:
        return img, lab, (0, 0)
    ph, pw = max(0, size - h), max(0, size - w)
    top, left = int(rng.integers(0, ph + 1)), int(rng.integers(0, pw + 1))
    img = np.pad(img, ((top, ph - top), (left, pw - left), (0, 0)), mode="edge")
    lab = np.pad(lab, ((top, ph - top), (left, pw - left)), mode="constant")
    return img, lab, (left, top)


def _crop_origin(lab: np.ndarray, size: int, rng: np.random.Generator, fg_p: float) -> tuple[int, int]:
    """Top-left of a ``size`` window; with probability ``fg_p`` it contains a random plant pixel."""
    h, w = lab.shape
    if fg_p > 0 and rng.random() < fg_p and (lab > 0).any():
        ys, xs = np.nonzero(lab)
        k = int(rng.integers(0, len(ys)))
        y0 = int(np.clip(ys[k] - rng.integers(size // 4, 3 * size // 4 + 1), 0, h - size))
        x0 = int(np.clip(xs[k] - rng.integers(size // 4, 3 * size // 4 + 1), 0, w - size))
        return y0, x0
    return int(rng.integers(0, h - size + 1)), int(rng.integers(0, w - size + 1))


def _rgb_to_hsv_shift(x: np.ndarray, hue: float, sat: float) -> np.ndarray:
    """Hue rotation and saturation scale on float RGB in [0, 1] via PIL's HSV (fast, uint8)."""
    img = Image.fromarray(np.clip(x * 255 + 0.5, 0, 255).astype(np.uint8)).convert("HSV")
    hsv = np.asarray(img).astype(np.int16)
    hsv[..., 0] = (hsv[..., 0] + int(round(hue * 255))) % 256
    hsv[..., 1] = np.clip(hsv[..., 1] * sat, 0, 255)
    return np.asarray(Image.fromarray(hsv.astype(np.uint8), "HSV").convert("RGB")).astype(np.float32) / 255.0


def backlight(x: np.ndarray, plant: np.ndarray, gain: float, desaturate: float) -> np.ndarray:
    """Darkens and desaturates the plant pixels of float RGB ``x`` (``plant``: bool mask).

    Real chamber views light the plant mostly from behind, through the white
    wall, so leaves read as dark olive silhouettes, while the renderer's plants
    are lit from the front. The mask edge is softened by a 3x3 box so the
    darkening has no hard seam where the renderer anti-aliased the leaf edge.
    """
    m = plant.astype(np.float32)
    p = np.pad(m, 1, mode="edge")
    h, w = m.shape
    soft = sum(p[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)) / 9.0
    lum = x @ np.array(LUMA, np.float32)
    dark = (lum[..., None] + (x - lum[..., None]) * (1.0 - desaturate)) * gain
    return x + (dark - x) * soft[..., None]


@dataclass
class PhotometricDraw:
    """One sample's photometric parameters, drawn before any pixel is touched.

    Drawing apart from applying lets the same draw be applied here (NumPy and
    PIL, in a loader process) or on the training device, batched
    (:mod:`phyllo_train.modes.photometric_torch`), so both paths train on the same
    random stream. Neutral values mean "op off".
    """

    backlight: bool = False
    backlight_gain: float = 1.0
    backlight_desaturate: float = 0.0
    hsv: bool = False               # hue/saturation op on (it quantises to uint8 on the CPU path)
    hue: float = 0.0                # fraction of the hue circle
    saturation: float = 1.0         # multiplier
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    brightness: float = 1.0
    contrast: float = 1.0
    gradient_angle: float = 0.0
    gradient: float = 0.0           # ramp amplitude; 0 = off
    gamma: float = 1.0
    fringe: tuple[int, int, int, int] = (0, 0, 0, 0)  # (dy, dx) of red, then of blue
    blur_sigma: float = 0.0         # 0 = off
    noise_sigma: float = 0.0        # 0..255 units; 0 = off
    noise_seed: int = 0             # seeds the noise field (< 2**24, exact in float32)
    jpeg_quality: int = 0           # 0 = off

    FIELDS = 22  # length of :meth:`to_vector`

    def to_vector(self) -> np.ndarray:
        """The draw as a flat float64 vector (the batched device path's input)."""
        v = [float(self.backlight), self.backlight_gain, self.backlight_desaturate, float(self.hsv), self.hue,
             self.saturation, *self.white_balance, self.brightness, self.contrast, self.gradient_angle,
             self.gradient, self.gamma, *map(float, self.fringe), self.blur_sigma, self.noise_sigma,
             float(self.noise_seed), float(self.jpeg_quality)]
        return np.asarray(v, np.float64)


def draw_photometric(cfg: AugmentConfig, rng: np.random.Generator, with_plant: bool = True) -> PhotometricDraw:
    """Draws the photometric ops of one sample; ``with_plant`` says whether a plant mask exists."""
    d = PhotometricDraw()
    if with_plant and cfg.backlight_p > 0 and rng.random() < cfg.backlight_p:
        d.backlight = True
        d.backlight_gain = float(rng.uniform(*cfg.backlight_gain))
        d.backlight_desaturate = float(rng.uniform(0.0, cfg.backlight_desaturate))
    if cfg.hue > 0 or cfg.saturation > 0:
        d.hsv = True
        d.hue = float(rng.uniform(-cfg.hue, cfg.hue))
        d.saturation = 1.0 + float(rng.uniform(-cfg.saturation, cfg.saturation))
    if cfg.white_balance > 0:
        d.white_balance = tuple(float(g) for g in 1.0 + rng.uniform(-cfg.white_balance, cfg.white_balance, size=3))
    if cfg.brightness > 0:
        d.brightness = 1.0 + float(rng.uniform(-cfg.brightness, cfg.brightness))
    if cfg.contrast > 0:
        d.contrast = 1.0 + float(rng.uniform(-cfg.contrast, cfg.contrast))
    if cfg.gradient > 0:
        d.gradient_angle = float(rng.uniform(0, 2 * np.pi))
        d.gradient = float(rng.uniform(0, cfg.gradient))
    if cfg.gamma != (1.0, 1.0):
        d.gamma = float(np.float32(np.exp(rng.uniform(np.log(cfg.gamma[0]), np.log(cfg.gamma[1])))))
    if cfg.fringe_p > 0 and rng.random() < cfg.fringe_p:
        r = rng.integers(-cfg.fringe_px, cfg.fringe_px + 1, size=2)
        b = rng.integers(-cfg.fringe_px, cfg.fringe_px + 1, size=2)
        d.fringe = (int(r[0]), int(r[1]), int(b[0]), int(b[1]))
    if rng.random() < cfg.blur_p:
        d.blur_sigma = float(rng.uniform(*cfg.blur_sigma))
    if rng.random() < cfg.noise_p:
        d.noise_sigma = float(rng.uniform(*cfg.noise_sigma))
        d.noise_seed = int(rng.integers(0, 2**24))
    if rng.random() < cfg.jpeg_p:
        d.jpeg_quality = int(rng.integers(cfg.jpeg_quality[0], cfg.jpeg_quality[1] + 1))
    return d


def apply_photometric(img: np.ndarray, d: PhotometricDraw, plant: np.ndarray | None = None) -> np.ndarray:
    """Applies a draw to a uint8 RGB image with NumPy and PIL; returns uint8.

    ``plant`` (bool, the image's shape) marks plant pixels for the backlight op.
    """
    x = img.astype(np.float32) / 255.0
    if d.backlight and plant is not None:
        x = backlight(x, plant, d.backlight_gain, d.backlight_desaturate)
    if d.hsv:
        x = _rgb_to_hsv_shift(x, d.hue, d.saturation)
    x = x * np.asarray(d.white_balance, np.float32)
    x = x * np.float32(d.brightness)
    if d.contrast != 1.0:
        m = x.mean()
        x = (x - m) * np.float32(d.contrast) + m
    if d.gradient > 0:
        # Uneven chamber lighting: a linear ramp in a random direction.
        h, w = x.shape[:2]
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        a = d.gradient_angle
        ramp = (np.cos(a) * (yy / h - 0.5) + np.sin(a) * (xx / w - 0.5)) * d.gradient
        x = x * (1.0 + ramp[..., None])
    x = np.clip(x, 0.0, 1.0)
    if d.gamma != 1.0:
        x = x ** np.float32(d.gamma)
    if any(d.fringe):
        # The real camera's lens and demosaicing leave green/magenta fringes on the
        # chamber's grey profiles; without them in training those edges look like leaves.
        for c, (dy, dx) in ((0, d.fringe[:2]), (2, d.fringe[2:])):
            x[..., c] = np.roll(x[..., c], (dy, dx), axis=(0, 1))
    out = Image.fromarray((x * 255 + 0.5).astype(np.uint8))
    if d.blur_sigma > 0:
        out = out.filter(ImageFilter.GaussianBlur(d.blur_sigma))
    arr = np.asarray(out)
    if d.noise_sigma > 0:
        noise = np.random.default_rng(d.noise_seed).normal(0, d.noise_sigma, size=arr.shape).astype(np.float32)
        arr = np.clip(arr.astype(np.float32) + noise, 0, 255).astype(np.uint8)
    if d.jpeg_quality > 0:
        buf = io.BytesIO()
        Image.fromarray(arr).save(buf, format="JPEG", quality=d.jpeg_quality)
        buf.seek(0)
        arr = np.asarray(Image.open(buf).convert("RGB"))
    return arr


def photometric(img: np.ndarray, cfg: AugmentConfig, rng: np.random.Generator,
                plant: np.ndarray | None = None) -> np.ndarray:
    """Colour / illumination / sensor augmentation of a uint8 RGB image; returns uint8.

    ``plant`` (bool, the image's shape) marks plant pixels for the backlight op;
    without it that op is skipped.
    """
    return apply_photometric(img, draw_photometric(cfg, rng, plant is not None), plant)


def augment(img: Image.Image, label: np.ndarray, cfg: AugmentConfig, rng: np.random.Generator,
            top_view: bool = False, label_divisor: int = 1000,
            zoom: tuple[int, float] = (0, 1.0), points: np.ndarray | None = None,
            ) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int], np.ndarray]:
    """Augment an RGB PIL image and its (H, W) label: :func:`augment_geometry`, then the
    photometric ops drawn next from the same ``rng``.

    Returns ``(rgb, label, window, points)`` as :func:`augment_geometry` does.
    """
    arr, label, window, pts, plant = augment_geometry(img, label, cfg, rng, top_view, label_divisor, zoom, points)
    return apply_photometric(arr, draw_photometric(cfg, rng), plant), label, window, pts


def augment_geometry(img: Image.Image, label: np.ndarray, cfg: AugmentConfig, rng: np.random.Generator,
                     top_view: bool = False, label_divisor: int = 1000,
                     zoom: tuple[int, float] = (0, 1.0), points: np.ndarray | None = None,
                     ) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int], np.ndarray, np.ndarray]:
    """The geometric half of :func:`augment`: zoom, scale, flips, padding and the crop.

    Returns ``(rgb, label, window, points, plant)``: the uint8 crop (size x size x 3) as rendered, the
    *whole* geometrically transformed label, the crop window
    ``(y0, x0, h, w)`` within it, and ``points`` ((K, 2) ``(x, y)``, pixel
    (i, j) spanning [i, i+1) x [j, j+1); leaf tips) moved with the label
    into its coordinates (empty when none are given). Targets are computed from the whole label so
    that instances cut by the crop keep the centre of the whole instance, as
    the daemon's tile stitching expects. ``zoom`` is the contract's
    ``(zoom_plant_height, max_zoom)``: a small plant is enlarged as the
    daemon enlarges it, before the scale jitter. Last comes the crop's plant
    mask (bool, leaf, stem or panicle), which the backlight op reads.
    """
    lo, hi = cfg.scale
    f = float(np.exp(rng.uniform(np.log(lo), np.log(hi)))) if hi > lo else 1.0
    pts = np.zeros((0, 2), np.float64) if points is None else np.array(points, np.float64).reshape(-1, 2)
    z = plant_zoom(label, label_divisor, *zoom)
    if z > 1.0:
        # Only the plant's surroundings are enlarged: a whole frame at 3x
        # would make every target costly, and the chamber far from the plant
        # is seen in unzoomed samples anyway.
        img, label, origin = _window_around_plant(img, label, label_divisor, margin=(cfg.crop or 256) // 2)
        pts -= origin
    if abs(z * f - 1.0) >= 1e-3:
        pts *= z * f  # _rescale samples output pixel i at input (i + 0.5) / f
    img, label = _rescale(img, label, z * f)
    arr = np.asarray(img.convert("RGB"))
    if rng.random() < cfg.hflip:
        arr, label = arr[:, ::-1], label[:, ::-1]
        pts[:, 0] = label.shape[1] - pts[:, 0]
    if top_view and cfg.rot90_top:
        k = int(rng.integers(0, 4))
        for _ in range(k):
            # np.rot90 once: new[i, j] = old[j, w - 1 - i], so (x, y) -> (y, w - x).
            pts = np.stack([pts[:, 1], label.shape[1] - pts[:, 0]], axis=1)
            arr, label = np.rot90(arr), np.rot90(label)
    size = cfg.crop if cfg.crop is not None else min(label.shape)
    arr, label, (left, top) = _pad_to(arr, label, size, rng)
    pts += (left, top)
    y0, x0 = _crop_origin(label, size, rng, cfg.fg_crop)
    plant = label[y0:y0 + size, x0:x0 + size] >= label_divisor  # class >= 1: leaf, stem or panicle
    arr = np.ascontiguousarray(arr[y0:y0 + size, x0:x0 + size])
    return arr, np.ascontiguousarray(label), (y0, x0, size, size), pts, plant
