"""The ball tracker's machine: waiting -> detecting -> tracking, as `components/ball_tracker`'s
(`src/tracker/`) does it, with OpenCV for the image work. No bus here: frames in as NumPy
arrays, `TrackOutput`s out.

- **Waiting**: no target; frames are ignored.
- **Detecting**: the image sampled on a grid (every `detection_step_px` pixels), HSV by OpenCV;
  cells within the target's colour tolerance form a mask, its 4-connected regions
  (`cv2.connectedComponentsWithStats`, split where depth jumps) are sized in metres from their
  median depth and the focal length, and the region closest to the target's diameter (within
  `size_tolerance`) wins. Nothing for `detect_timeout_s`: `detection_timed_out`, back to waiting.
- **Tracking**: a hue-saturation-depth histogram of the ball (`cv2.calcHist`) is back-projected
  (`cv2.calcBackProject`) onto a region of interest around the window predicted from the image
  velocity, and `cv2.CamShift` moves and sizes the window (again while it still grows). The
  result is verified (the ball's colour pixels at its depth must measure the target's diameter
  within `size_tolerance`); when it is, the histogram's ranges are re-centred on the window's
  pixels and the histogram rebuilt. `max_failed_frames` rejections in a row: `lost`, detecting
  again; a rejection while the last good window touched the border, or the prediction left the
  image: `out_of_view` first (once per track).

The 3D centre is the sphere's centre: per ball pixel with depth, the distance along the ray
through the ball's centroid at which a sphere of the target's radius through that surface point
is centred (surface depth plus radius, along the ray); the median over the pixels.

Conventions as in Rust: pixel (u, v) = (column, row), pixel centres at integer coordinates;
points in the camera's optical frame (z forward, x right, y down), metres; hue in degrees.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import cv2
import numpy as np

WAITING, DETECTING, TRACKING = "waiting", "detecting", "tracking"
DETECTED, OUT_OF_VIEW, LOST, DETECTION_TIMED_OUT = (
    "detected",
    "out_of_view",
    "lost",
    "detection_timed_out",
)

#: The shortest time between two frames over which the image velocity is measured, s.
MIN_VELOCITY_DT_S = 0.005
#: Time since the ball was last held after which frames were dropped: a ball not where
#: predicted is then looked for over the whole frame, s.
FRAME_GAP_S = 0.1
#: The fastest a tracked ball is taken to cross the image, px/s.
MAX_IMAGE_SPEED_PX_PER_S = 3200.0
#: A depth no histogram range holds: marks the pixels the histogram must not see.
_OUTSIDE = np.float32(-1e9)


class InvalidTarget(ValueError):
    """A target out of range (a hue that is no number, a saturation outside [0, 1], a diameter
    that is not positive)."""


class InvalidFrame(ValueError):
    """A frame whose sizes or intrinsics are inconsistent."""


@dataclasses.dataclass(frozen=True)
class Target:
    """What to look for: a ball of one colour (HSV hue, degrees; saturation) and size (m)."""

    hue_deg: float
    saturation: float
    diameter_m: float

    def checked(self) -> Target:
        """The target with its hue in [0, 360); raises `InvalidTarget`."""
        h, s, d = float(self.hue_deg), float(self.saturation), float(self.diameter_m)
        if not (math.isfinite(h) and 0.0 <= s <= 1.0):
            raise InvalidTarget(
                f"hue {h} deg, saturation {s} (needs finite hue, saturation in [0, 1])"
            )
        if not (math.isfinite(d) and d > 0.0):
            raise InvalidTarget(f"diameter {d} m (needs > 0)")
        return Target(h % 360.0, s, d)


@dataclasses.dataclass(frozen=True)
class Config:
    """Tuning; the Rust tracker's defaults (`TrackerConfig`)."""

    hue_tolerance_deg: float = 18.0
    saturation_tolerance: float = 0.3
    min_value: float = 0.12
    detection_step_px: int = 4
    min_region_cells: int = 4
    size_tolerance: float = 0.35
    detect_timeout_s: float = 10.0
    max_failed_frames: int = 5
    hist_bins: tuple[int, int, int] = (16, 8, 8)
    meanshift_max_iterations: int = 10
    meanshift_epsilon_px: float = 0.5
    range_sigmas: float = 2.5
    border_margin_px: float = 6.0


class Intrinsics(NamedTuple):
    fx: float
    fy: float
    cx: float
    cy: float

    def valid(self) -> bool:
        return (
            all(math.isfinite(v) for v in self)
            and self.fx > 0.0
            and self.fy > 0.0
        )


@dataclasses.dataclass
class TrackOutput:
    """The tracker's result for one frame."""

    state: str
    #: (x, y, width, height), pixels, when the ball was found in this frame.
    window: tuple[int, int, int, int] | None = None
    centre_px: tuple[float, float] | None = None
    centre_m: tuple[float, float, float] | None = None
    measured_diameter_m: float | None = None
    confidence: float = 0.0
    events: list[str] = dataclasses.field(default_factory=list)


def _lo(v: float) -> int:
    """floor(v) as a pixel index >= 0 (NaN and negatives: 0)."""
    if not v > 0.0:
        return 0
    return int(math.floor(min(v, 1e9)))


def _hi(v: float) -> int:
    """ceil(v) as a pixel index >= 0 (NaN and negatives: 0)."""
    if not v > 0.0:
        return 0
    return int(math.ceil(min(v, 1e9)))


@dataclasses.dataclass
class FWin:
    """A floating window: centre and half sizes, pixels."""

    cx: float
    cy: float
    hw: float
    hh: float

    def clip(self, w: int, h: int) -> tuple[int, int, int, int]:
        """Pixel bounds [x0, x1) x [y0, y1) clipped to the image; empty when outside."""
        x0, y0 = _lo(self.cx - self.hw), _lo(self.cy - self.hh)
        x1, y1 = min(_hi(self.cx + self.hw), w), min(_hi(self.cy + self.hh), h)
        return min(x0, x1), min(y0, y1), x1, y1

    def window(self, w: int, h: int) -> tuple[int, int, int, int]:
        x0, y0, x1, y1 = self.clip(w, h)
        return x0, y0, x1 - x0, y1 - y0

    def scaled(self, k: float) -> FWin:
        return FWin(self.cx, self.cy, self.hw * k, self.hh * k)


@dataclasses.dataclass
class Ranges:
    """The histogram's ranges: hue relative to the target's (deg), saturation, depth (mm)."""

    h: tuple[float, float]
    s: tuple[float, float]
    d: tuple[float, float]

    def flat(self) -> list[float]:
        return [*self.h, *self.s, *self.d]

    def usable(self) -> bool:
        return all(
            math.isfinite(lo) and math.isfinite(hi) and hi > lo
            for lo, hi in (self.h, self.s, self.d)
        )


class Roi:
    """A region of interest decoded once: hue relative to the target, saturation, depth (mm),
    and whether each pixel has the target's colour. `x0, y0`: its origin in the image."""

    def __init__(self, rgb, depth, target: Target, config: Config, box):
        x0, y0, x1, y1 = box
        self.x0, self.y0 = x0, y0
        self.w, self.h = x1 - x0, y1 - y0
        dh, s, v = _hsv(rgb[y0:y1, x0:x1], target)
        self.dh, self.s = dh, s
        self.d = depth[y0:y1, x0:x1].astype(np.float32)
        self.ok = (
            (v >= config.min_value)
            & (np.abs(dh) <= config.hue_tolerance_deg)
            & (np.abs(s - target.saturation) <= config.saturation_tolerance)
        )

    def hsd(self) -> np.ndarray:
        """The three channels the histogram is made of, as one float32 image; pixels without
        the colour or without depth are outside every range."""
        usable = self.ok & (self.d > 0)
        return np.dstack((np.where(usable, self.dh, _OUTSIDE), self.s, self.d))


def _hsv(rgb: np.ndarray, target: Target):
    """Hue relative to the target's, wrapped to (-180, 180] (deg), saturation and value of an
    RGB8 block, by OpenCV in float (hue in [0, 360))."""
    f = rgb.astype(np.float32)
    f *= np.float32(1.0 / 255.0)
    hsv = cv2.cvtColor(f, cv2.COLOR_RGB2HSV)
    dh = np.mod(hsv[..., 0] - np.float32(target.hue_deg), np.float32(360.0))
    dh[dh > 180.0] -= 360.0
    return dh, hsv[..., 1], hsv[..., 2]


def _upper_median(a: np.ndarray):
    """The element at len/2 in sorted order (the Rust tracker's `select_nth_unstable(len / 2)`)."""
    mid = a.size // 2
    return np.partition(a, mid)[mid]


def equivalent_diameter_m(area_px: float, z_surface_m: float, f_px: float) -> float | None:
    """Metric diameter of a sphere whose silhouette covers `area_px` pixels, given the median
    depth of its visible surface and the focal length: the silhouette lies at the centre depth,
    about 0.354 D behind the median surface depth, so D = d (z + 0.354 D) / f, solved for D."""
    if not (area_px > 0.0 and z_surface_m > 0.0 and f_px > 0.0):
        return None
    d_px = 2.0 * math.sqrt(area_px / math.pi)
    denom = f_px - 0.5 * math.sqrt(0.5) * d_px
    return d_px * z_surface_m / denom if denom > 0.0 else None


def ball_depth_band(med_mm: float, target: Target) -> tuple[float, float]:
    """Depth band (mm) of a ball's visible surface around its median surface depth."""
    half = target.diameter_m * 1000.0 * 0.75 + 20.0 + 0.01 * med_mm
    return max(med_mm - half, 1.0), med_mm + half


@dataclasses.dataclass
class Measurement:
    centroid: tuple[float, float] = (0.0, 0.0)
    centre_m: tuple[float, float, float] | None = None
    diameter_m: float | None = None
    size_ok: bool = False
    confidence: float = 0.0


@dataclasses.dataclass
class _Track:
    win: FWin
    ranges: Ranges
    hist: np.ndarray
    failures: int = 0
    velocity: tuple[float, float] = (0.0, 0.0)
    last_good_time_s: float = 0.0
    last_good_win: FWin | None = None
    out_of_view_reported: bool = False


class BallTracker:
    """Feed it frames with `process`; give it a target with `set_target`."""

    def __init__(self, config: Config | None = None):
        self.config = config or Config()
        self.target: Target | None = None
        self.state = WAITING
        self._detect_since_s: float | None = None
        self._track: _Track | None = None
        #: Counters of unusual input (as the Rust tracker's `TrackerStats`).
        self.stats = {"frames": 0, "frames_without_depth": 0, "rejected_results": 0, "gap_searches": 0}
        c = self.config
        self._crit = (
            cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT,
            c.meanshift_max_iterations,
            c.meanshift_epsilon_px,
        )

    def set_target(self, target: Target | None) -> None:
        """Sets (`None`: clears) the target: detecting, or waiting. Raises `InvalidTarget`
        (and changes nothing) for a target out of range."""
        target = target.checked() if target is not None else None
        self.target = target
        self._track = None
        self._detect_since_s = None
        self.state = DETECTING if target is not None else WAITING

    def process(
        self, rgb: np.ndarray, depth: np.ndarray, k: Intrinsics, now_s: float
    ) -> TrackOutput:
        """One frame (RGB8 `h x w x 3`, depth `h x w` uint16 mm, 0 = none) observed at `now_s`
        (s). Raises `InvalidFrame` (and changes nothing) for an inconsistent frame."""
        if not math.isfinite(now_s):
            raise InvalidFrame(f"time {now_s} s")
        h, w = depth.shape[:2]
        if w == 0 or h == 0 or rgb.shape[:2] != (h, w) or rgb.ndim != 3 or rgb.shape[2] != 3:
            raise InvalidFrame(f"colour {rgb.shape} and depth {depth.shape} do not match")
        if not k.valid():
            raise InvalidFrame(f"intrinsics {tuple(k)}")
        self.stats["frames"] += 1
        has_depth = bool(depth.any())
        if not has_depth:
            self.stats["frames_without_depth"] += 1
        out = TrackOutput(state=self.state)
        target = self.target
        if target is None:
            self.state = WAITING
            out.state = self.state
            return out
        if self.state == TRACKING:
            self._track_step(rgb, depth, k, target, now_s, has_depth, out)
        # Detect in the same frame when not tracking (also right after a loss).
        if self.state == DETECTING:
            if self._detect_since_s is None:
                self._detect_since_s = now_s
            since = self._detect_since_s
            if has_depth and self._detect(rgb, depth, k, target, now_s, out):
                out.events.append(DETECTED)
            elif now_s - since >= self.config.detect_timeout_s:
                out.events.append(DETECTION_TIMED_OUT)
                self.target = None
                self._detect_since_s = None
                self.state = WAITING
        out.state = self.state
        return out

    # -- tracking ---------------------------------------------------------------------------

    def _track_step(self, rgb, depth, k, target, now_s, has_depth, out: TrackOutput) -> None:
        track = self._track
        self._track = None
        if track is None:
            self.state = DETECTING
            return
        h, w = depth.shape[:2]
        dt = min(max(now_s - track.last_good_time_s, 0.0), 1.0)
        lg = track.last_good_win
        predicted = FWin(
            lg.cx + track.velocity[0] * dt, lg.cy + track.velocity[1] * dt, track.win.hw, track.win.hh
        )
        result = self._camshift(rgb, depth, k, target, track, predicted, 0) if has_depth else None
        good = result is not None and result[1].size_ok
        # Not where predicted, and long enough since it was last held that it may be anywhere
        # the search did not cover: look over the whole frame, in this frame (no event: the
        # track goes on from there).
        searched = max(predicted.hw, predicted.hh) * (2.0 + min(track.failures, 4))
        if (
            has_depth
            and not good
            and dt >= FRAME_GAP_S
            and MAX_IMAGE_SPEED_PX_PER_S * dt > searched
        ):
            self.stats["gap_searches"] += 1
            if self._detect(rgb, depth, k, target, now_s, out):
                return
        if good:
            win, m = result
            if dt >= MIN_VELOCITY_DT_S:
                vx = (win.cx - lg.cx) / dt
                vy = (win.cy - lg.cy) / dt
                v = (0.5 * track.velocity[0] + 0.5 * vx, 0.5 * track.velocity[1] + 0.5 * vy)
                speed = math.hypot(*v)
                s = MAX_IMAGE_SPEED_PX_PER_S / speed if speed > MAX_IMAGE_SPEED_PX_PER_S else 1.0
                track.velocity = (v[0] * s, v[1] * s)
            track.win = win
            track.last_good_win = win
            track.last_good_time_s = now_s
            track.failures = 0
            self._fill(out, win, m, w, h)
            self._track = track
            return
        self.stats["rejected_results"] += 1
        track.failures += 1
        margin = self.config.border_margin_px
        pred_outside = (
            predicted.cx < 0.0 or predicted.cy < 0.0 or predicted.cx >= w or predicted.cy >= h
        )
        at_border = (
            lg.cx - lg.hw <= margin
            or lg.cy - lg.hh <= margin
            or lg.cx + lg.hw >= w - margin
            or lg.cy + lg.hh >= h - margin
        )
        if (at_border or pred_outside) and not track.out_of_view_reported:
            track.out_of_view_reported = True
            out.events.append(OUT_OF_VIEW)
        if track.failures >= self.config.max_failed_frames:
            out.events.append(LOST)
            self.state = DETECTING
            self._detect_since_s = now_s
        else:
            self._track = track

    @staticmethod
    def _fill(out: TrackOutput, win: FWin, m: Measurement, w: int, h: int) -> None:
        out.window = win.window(w, h)
        out.centre_px = m.centroid
        out.centre_m = m.centre_m
        out.measured_diameter_m = m.diameter_m
        out.confidence = m.confidence

    def _camshift(self, rgb, depth, k, target, track: _Track, start: FWin, attempt: int):
        """CamShift from `start` on the back-projection of the track's histogram over a region
        of interest around it; returns (window, measurement), or None when there is no
        probability mass. Adapts the track's ranges and histogram when the result is good."""
        h, w = depth.shape[:2]
        grow = 2.0 + min(track.failures, 4)
        rx0, ry0, rx1, ry1 = FWin(
            start.cx, start.cy, start.hw * grow + 8.0, start.hh * grow + 8.0
        ).clip(w, h)
        if rx1 <= rx0 or ry1 <= ry0:
            return None
        roi = Roi(rgb, depth, target, self.config, (rx0, ry0, rx1, ry1))
        if not track.ranges.usable():
            return None
        hsd = roi.hsd()
        prob = cv2.calcBackProject(
            [hsd], [0, 1, 2], cv2.Mat(track.hist, wrap_channels=False), track.ranges.flat(), 1.0
        )

        def rect(win: FWin):
            """`win` as an OpenCV rectangle in the region (x, y, w, h)."""
            x0, y0, x1, y1 = win.clip(w, h)
            x0, x1 = min(max(x0, rx0), rx1) - rx0, min(max(x1, rx0), rx1) - rx0
            y0, y1 = min(max(y0, ry0), ry1) - ry0, min(max(y1, ry0), ry1) - ry0
            return x0, y0, x1 - x0, y1 - y0

        def mass(r) -> float:
            x, y, rw, rh = r
            return float(prob[y : y + rh, x : x + rw].sum()) if rw > 0 and rh > 0 else 0.0

        win = FWin(start.cx, start.cy, start.hw, start.hh)
        # Nothing under the start window (the ball moved more than its size): from the centroid
        # of the whole region.
        if mass(rect(win)) <= 0.0:
            m = cv2.moments(prob)
            if m["m00"] <= 0.0:
                return None
            win.cx = m["m10"] / m["m00"] + rx0
            win.cy = m["m01"] / m["m00"] + ry0
        # CamShift, again while the window still grows (one that caught part of the ball).
        for _round in range(4):
            r = rect(win)
            if r[2] <= 0 or r[3] <= 0:
                return None
            box, (x, y, bw, bh) = cv2.CamShift(prob, r, self._crit)
            if bw <= 0 or bh <= 0 or mass((x, y, bw, bh)) <= 0.0:
                return None
            old_hw, old_hh = win.hw, win.hh
            win = FWin(x + bw / 2.0 - 0.5 + rx0, y + bh / 2.0 - 0.5 + ry0, bw / 2.0, bh / 2.0)
            if max(win.hw / max(old_hw, 1e-6), win.hh / max(old_hh, 1e-6)) < 1.1:
                break
        # The ball reached the edge of the region (it moved farther than predicted): once, again
        # from a region centred on it.
        bx0, by0, bx1, by1 = win.scaled(1.6).clip(w, h)
        if attempt == 0 and (bx0 < rx0 or by0 < ry0 or bx1 > rx1 or by1 > ry1):
            return self._camshift(
                rgb, depth, k, target, track, FWin(win.cx, win.cy, start.hw, start.hh), 1
            )
        x, y, bw, bh = rect(win)
        wb = (x, y, x + bw, y + bh)
        # Measured over a slightly larger window: one a pixel too small would clip the ball.
        x, y, mw, mh = rect(win.scaled(1.2))
        m = self._measure(k, target, roi, (x, y, x + mw, y + mh), track.ranges.d)
        if m.size_ok:
            ranges = self._adapted_ranges(target, track.ranges, hsd, wb)
            if ranges is not None:
                track.ranges = ranges
            track.hist = self._hist(hsd, track.ranges, wb)
        return win, m

    def _hist(self, hsd: np.ndarray, ranges: Ranges, b) -> np.ndarray:
        """The model histogram of the pixels in `b` (region bounds), normalised to a maximum
        of 1 (zeros when the ranges are empty)."""
        bins = list(self.config.hist_bins)
        x0, y0, x1, y1 = b
        if not ranges.usable() or x1 <= x0 or y1 <= y0:
            return np.zeros(bins, np.float32)
        block = np.ascontiguousarray(hsd[y0:y1, x0:x1])
        hist = cv2.calcHist([block], [0, 1, 2], None, bins, ranges.flat())
        top = float(hist.max())
        if top > 0.0:
            hist *= np.float32(1.0 / top)
        return hist

    def _adapted_ranges(self, target: Target, cur: Ranges, hsd: np.ndarray, b) -> Ranges | None:
        """The window's in-range pixels' mean +- `range_sigmas` sd, hue and saturation within
        the target's colour tolerance, depth at least two diameters either side."""
        x0, y0, x1, y1 = b
        block = hsd[y0:y1, x0:x1].reshape(-1, 3).astype(np.float64)
        inside = np.ones(len(block), bool)
        for i, (lo, hi) in enumerate((cur.h, cur.s, cur.d)):
            inside &= (block[:, i] >= lo) & (block[:, i] <= hi)
        px = block[inside]
        if len(px) < 10:
            return None
        mean = px.mean(axis=0)
        sd = np.sqrt(np.maximum((px * px).mean(axis=0) - mean * mean, 0.0))
        c = self.config
        kk = c.range_sigmas
        ht, st, ts = c.hue_tolerance_deg, c.saturation_tolerance, target.saturation
        hw = max(kk * sd[0], 6.0)
        sw = max(kk * sd[1], 0.08)
        dw = max(kk * sd[2], 2.0 * target.diameter_m * 1000.0)
        return Ranges(
            h=(max(mean[0] - hw, -ht), min(mean[0] + hw, ht)),
            s=(max(mean[1] - sw, ts - st), min(mean[1] + sw, ts + st)),
            d=(max(mean[2] - dw, 1.0), mean[2] + dw),
        )

    # -- measuring ---------------------------------------------------------------------------

    def _measure(self, k: Intrinsics, target: Target, roi: Roi, b, band_mm) -> Measurement:
        """The ball inside `b` (region bounds): colour area, centroid, size, 3D centre."""
        x0, y0, x1, y1 = b
        if x1 <= x0 or y1 <= y0:
            return Measurement()
        ok = roi.ok[y0:y1, x0:x1]
        d = roi.d[y0:y1, x0:x1]
        # The ball's surface depth: the median over colour pixels in the given band; its pixels
        # are then the colour pixels near that depth (or without depth).
        in_band = d[ok & (d >= band_mm[0]) & (d <= band_mm[1])]
        if in_band.size < 3:
            return Measurement()
        lo, hi = ball_depth_band(float(_upper_median(in_band)), target)
        ball = ok & ((d == 0) | ((d >= lo) & (d <= hi)))
        vs, us = np.nonzero(ball)
        area = us.size
        with_depth = d[vs, us] > 0
        if area == 0 or np.count_nonzero(with_depth) < 3:
            return Measurement()
        us = us.astype(np.float64) + (roi.x0 + x0)
        vs = vs.astype(np.float64) + (roi.y0 + y0)
        centroid = (float(us.mean()), float(vs.mean()))
        pu, pv = us[with_depth], vs[with_depth]
        z = d[ball][with_depth].astype(np.float64) / 1000.0
        z_surface = float(_upper_median(z))
        f = (k.fx + k.fy) / 2.0
        diameter = equivalent_diameter_m(float(area), z_surface, f)
        ratio = diameter / target.diameter_m if diameter is not None else math.inf
        tol = self.config.size_tolerance
        size_ok = abs(ratio - 1.0) <= tol
        # The sphere's centre along the centroid's ray, from the pixels near the surface depth.
        r = target.diameter_m / 2.0
        ray = np.array([(centroid[0] - k.cx) / k.fx, (centroid[1] - k.cy) / k.fy, 1.0])
        ray /= np.linalg.norm(ray)
        near = (z >= z_surface - 2.0 * r - 0.02) & (z <= z_surface + 2.0 * r + 0.02)
        centre = None
        if np.count_nonzero(near) >= 3:
            zn = z[near]
            p = np.stack(((pu[near] - k.cx) * zn / k.fx, (pv[near] - k.cy) * zn / k.fy, zn), axis=1)
            a = p @ ray
            perp2 = np.maximum((p * p).sum(axis=1) - a * a, 0.0)
            t = a + np.sqrt(np.maximum(r * r - perp2, 0.0))
            centre = tuple(float(c) for c in ray * float(_upper_median(t)))
        size_score = min(max(1.0 - abs(ratio - 1.0) / tol, 0.0), 1.0)
        # Depth support: the share of ball pixels with depth (80 % counts as full).
        support = min(np.count_nonzero(with_depth) / area / 0.8, 1.0)
        return Measurement(
            centroid=centroid,
            centre_m=centre,
            diameter_m=diameter,
            size_ok=size_ok,
            confidence=min(max(size_score * support, 0.0), 1.0) if size_ok else 0.0,
        )

    # -- detecting ---------------------------------------------------------------------------

    def _detect(self, rgb, depth, k: Intrinsics, target: Target, now_s: float, out) -> bool:
        """Detection over the whole frame; on success starts tracking and fills `out`."""
        c = self.config
        h, w = depth.shape[:2]
        step = max(int(c.detection_step_px), 1)
        # The grid: the pixel at the centre of each cell (clamped into the image).
        ys = np.minimum(np.arange(0, h, step) + step // 2, h - 1)
        xs = np.minimum(np.arange(0, w, step) + step // 2, w - 1)
        cells = rgb[ys[:, None], xs[None, :]]
        cell_depth = depth[ys[:, None], xs[None, :]].astype(np.int32)
        dh, s, v = _hsv(cells, target)
        mask = (
            (v >= c.min_value)
            & (np.abs(dh) <= c.hue_tolerance_deg)
            & (np.abs(s - target.saturation) <= c.saturation_tolerance)
        )
        n_labels, labels, stats, _ = cv2.connectedComponentsWithStats(
            mask.astype(np.uint8), connectivity=4
        )
        jump_mm = max(int(min(target.diameter_m * 1000.0 * 0.5, 65535.0)), 40)
        f = (k.fx + k.fy) / 2.0
        max_err = math.log(1.0 + c.size_tolerance)
        best = None  # (error, (x0, y0, x1, y1) pixels, median depth mm)
        for label in range(1, n_labels):
            gx, gy, gw, gh, n = (int(x) for x in stats[label])
            if n < c.min_region_cells:
                continue
            inside = labels[gy : gy + gh, gx : gx + gw] == label
            dcells = cell_depth[gy : gy + gh, gx : gx + gw]
            ds = dcells[inside]
            ds = ds[ds > 0]
            if ds.size == 0 or int(ds.max()) - int(ds.min()) <= jump_mm:
                regions = [(n, (gx, gy, gx + gw, gy + gh), ds)]
            else:
                # Depth jumps inside: regions split where neighbours' depths differ (a ball in
                # front of a same-coloured object is a region of its own).
                regions = [
                    (rn, (gx + b0, gy + b1, gx + b2, gy + b3), rd)
                    for rn, (b0, b1, b2, b3), rd in _split_by_depth(inside, dcells, jump_mm)
                ]
            for rn, (bx0, by0, bx1, by1), rd in regions:
                if rn < c.min_region_cells or rd.size < 3:
                    continue
                med = int(_upper_median(rd))
                d_m = equivalent_diameter_m(float(rn * step * step), med / 1000.0, f)
                if d_m is None:
                    continue
                err = abs(math.log(d_m / target.diameter_m))
                if err <= max_err and (best is None or err < best[0]):
                    box = (bx0 * step, by0 * step, min(bx1 * step, w), min(by1 * step, h))
                    best = (err, box, float(med))
        if best is None:
            return False
        _, (x0, y0, x1, y1), med_mm = best
        band = ball_depth_band(med_mm, target)
        # Refine at full resolution: the region with a cell of margin, the bounding box of the
        # ball's colour pixels at its depth.
        ex0, ey0 = max(x0 - step, 0), max(y0 - step, 0)
        ex1, ey1 = min(x1 + step, w), min(y1 + step, h)
        roi = Roi(rgb, depth, target, c, (ex0, ey0, ex1, ey1))
        ball = roi.ok & ((roi.d == 0) | ((roi.d >= band[0]) & (roi.d <= band[1])))
        vs, us = np.nonzero(ball)
        if us.size == 0:
            return False
        fx0, fy0, fx1, fy1 = int(us.min()), int(vs.min()), int(us.max()) + 1, int(vs.max()) + 1
        wb = (fx0, fy0, fx1, fy1)
        m = self._measure(k, target, roi, wb, band)
        if not m.size_ok:
            return False
        win = FWin(
            ex0 + fx0 + (fx1 - fx0) / 2.0 - 0.5,
            ey0 + fy0 + (fy1 - fy0) / 2.0 - 0.5,
            (fx1 - fx0) / 2.0,
            (fy1 - fy0) / 2.0,
        )
        # The first ranges: the colour tolerance, and the ball's depth band.
        z_mm = m.centre_m[2] * 1000.0 if m.centre_m is not None else 1000.0
        dmm = target.diameter_m * 1000.0
        ranges = Ranges(
            h=(-c.hue_tolerance_deg, c.hue_tolerance_deg),
            s=(target.saturation - c.saturation_tolerance, target.saturation + c.saturation_tolerance),
            d=(max(z_mm - 2.0 * dmm, 1.0), z_mm + dmm),
        )
        hist = self._hist(roi.hsd(), ranges, wb)
        self._track = _Track(
            win=win, ranges=ranges, hist=hist, last_good_time_s=now_s, last_good_win=win
        )
        self.state = TRACKING
        self._detect_since_s = None
        self._fill(out, win, m, w, h)
        return True


def _split_by_depth(inside: np.ndarray, depth: np.ndarray, jump_mm: int):
    """The 4-connected regions of the cells `inside`, split where neighbouring depths differ
    by more than `jump_mm` (a cell without depth joins either side, carrying the depth it was
    reached with): the Rust tracker's flood fill, for a component whose depths jump. Yields
    (cells, (x0, y0, x1, y1) in cells, depths > 0 as an array)."""
    gh, gw = inside.shape
    mask = inside.ravel().tolist()
    dep = depth.ravel().tolist()
    label = [False] * (gw * gh)
    for start in range(gw * gh):
        if not mask[start] or label[start]:
            continue
        label[start] = True
        stack = [(start, dep[start])]
        n, bx0, by0, bx1, by1 = 0, gw, gh, 0, 0
        depths = []
        while stack:
            j, carried = stack.pop()
            gx, gy = j % gw, j // gw
            n += 1
            bx0, by0 = min(bx0, gx), min(by0, gy)
            bx1, by1 = max(bx1, gx + 1), max(by1, gy + 1)
            if dep[j] > 0:
                depths.append(dep[j])
                d = dep[j]
            else:
                d = carried
            for kk, ok in ((j - 1, gx > 0), (j + 1, gx + 1 < gw), (j - gw, gy > 0), (j + gw, gy + 1 < gh)):
                if not ok or not mask[kk] or label[kk]:
                    continue
                dk = dep[kk]
                if d == 0 or dk == 0 or abs(d - dk) <= jump_mm:
                    label[kk] = True
                    stack.append((kk, dk if dk > 0 else d))
        yield n, (bx0, by0, bx1, by1), np.array(depths, np.int32)
