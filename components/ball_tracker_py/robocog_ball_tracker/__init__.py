"""`ball_tracker` in Python: the Rust tracker's topics and state machine, with OpenCV's CamShift.

    python -m robocog run robocog_ball_tracker [--target-hue H --target-saturation S
        --target-diameter D] [--no-dr] [shared flags: --namespace, --connect, ...]

Subscribes:
- `vision/rgbd` (`RgbdFrame`), read in place (NumPy views of the received sample). The frames
  are tracked at their own stamps (the tracker's clock). When frames queue up behind the
  tracker, the newest is tracked (a subscription queue of one) and the others are counted
  (`skipped_frames`, from the gaps in the camera's sequence numbers).
- `vision/ball_target` (`BallTarget`): what to look for, `active = False` clears it. Applied
  from the first frame stamped at or after the target's stamp (at once when unstamped, or when
  its stamp leads the frames by more than a second: `targets_ahead_of_frames`). The flags
  `--target-hue --target-saturation --target-diameter` give one at start.

Publishes, per tracked frame: `vision/ball` (`BallTrack`: state, window, centroid, centre in
the camera frame, diameter, confidence and, through the DR, the centre in `world` and in the
robot's base frame), stamped with the frame's stamp in its `frame_id`; `vision/ball_events`
(`BallEvent`: detected, out_of_view, lost, detection_timed_out).

Calls (unless `--no-dr`): `dr/transform` and `dr/update` (see `robocog_ball_tracker.dr`).

Bad input: an inconsistent frame is counted (`bad_frames`), logged at most once a second and
skipped; an out-of-range target is counted (`bad_targets`) and ignored.
"""

from __future__ import annotations

import argparse
import collections
import math

from robocog import images, msg
from robocog.component import Component, ConfigError, main

from .dr import DrLink, DrOptions
from .ratelimit import RateLimiter
from .tracker import (
    TRACKING,
    BallTracker,
    Config,
    Intrinsics,
    InvalidFrame,
    InvalidTarget,
    Target,
    TrackOutput,
)

__all__ = ["BallTrackerComponent", "main"]

#: How far a target's stamp may lead the frames before it is taken for clocks that disagree
#: and applied at once, ns.
TARGET_LEAD_NS = 1_000_000_000
#: Targets held for later frames beyond which the oldest applies at once.
PENDING_TARGETS = 16
#: Largest frame accepted from the bus, pixels (anything larger is garbage).
MAX_PIXELS = 1 << 24

_DR_CALLS = [
    ("dr/transform", msg.TransformRequest, msg.TransformReply),
    ("dr/update", msg.UpdateRequest, msg.UpdateReply),
]


def stamp_ns(header: msg.Header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def time_of(ns: int) -> msg.Time:
    return msg.Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def frame_arrays(frame: msg.RgbdFrame):
    """The colour and depth images (NumPy views of the sample) and intrinsics of a frame;
    raises InvalidFrame when its sizes or intrinsics are inconsistent."""
    rgb, depth = frame.rgb, frame.depth
    w, h = rgb.width, rgb.height
    if (depth.width, depth.height) != (w, h):
        raise InvalidFrame(f"colour {w}x{h} and depth {depth.width}x{depth.height} differ")
    if w * h == 0:
        raise InvalidFrame(f"a frame of {w}x{h} pixels")
    if w * h > MAX_PIXELS:
        raise InvalidFrame(f"a frame of {w}x{h} pixels is larger than {MAX_PIXELS} pixels")
    if len(rgb.data) != w * h * 3 or len(depth.data) != w * h * 2:
        raise InvalidFrame(
            f"buffers of {len(rgb.data)} colour and {len(depth.data)} depth bytes for {w}x{h} "
            "pixels"
        )
    kk = frame.camera_info.k
    if len(kk) != 9:
        raise InvalidFrame(f"intrinsics of {len(kk)} numbers")
    k = Intrinsics(float(kk[0]), float(kk[4]), float(kk[2]), float(kk[5]))
    if not k.valid():
        raise InvalidFrame(f"intrinsics fx {k.fx}, fy {k.fy}, cx {k.cx}, cy {k.cy}")
    try:
        return images.rgb(frame), images.depth_mm(frame), k
    except ValueError as e:
        raise InvalidFrame(str(e)) from None


class BallTrackerComponent(Component):
    NAME = "ball_tracker"
    ABOUT = (
        "Tracks a coloured ball in `vision/rgbd` (OpenCV's CamShift); publishes `vision/ball` "
        "and `vision/ball_events`."
    )
    SUBSCRIBES = [("vision/rgbd", msg.RgbdFrame), ("vision/ball_target", msg.BallTarget)]
    PUBLISHES = [("vision/ball", msg.BallTrack), ("vision/ball_events", msg.BallEvent)]
    CALLS = list(_DR_CALLS)

    @classmethod
    def interface(cls, args=None):
        """With `--no-dr`, no `dr/*` calls are declared (as the Rust tracker's)."""
        interface = super().interface(args)
        if args is not None and args.no_dr:
            interface["calls"] = []
        return interface

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        default = Config()
        parser.add_argument(
            "--target-hue", type=float, help="target hue, degrees [0, 360) (with "
            "--target-saturation and --target-diameter)"
        )
        parser.add_argument("--target-saturation", type=float, help="target saturation, [0, 1]")
        parser.add_argument("--target-diameter", type=float, help="target diameter, m")
        parser.add_argument(
            "--detect-timeout-s",
            type=float,
            default=default.detect_timeout_s,
            help="detecting this long without a match drops the target (back to waiting), s "
            "(default %(default)s)",
        )
        parser.add_argument(
            "--every-frame",
            action="store_true",
            help="track every frame, in order, even when behind (offline evaluation)",
        )
        parser.add_argument(
            "--no-dr",
            action="store_true",
            help="do not use the deep representation: tracks in the camera frame only, no ball "
            "node updates, and no dr/* calls declared",
        )
        parser.add_argument(
            "--ball-node", default="ball", help="the DR node of the ball (its parent: world)"
        )
        parser.add_argument(
            "--robot-frame", default="base_footprint", help="the robot's base frame in the DR"
        )
        parser.add_argument(
            "--dr-update-confidence",
            type=float,
            default=0.5,
            help="smallest track confidence, [0, 1], that updates the DR's ball node",
        )
        parser.add_argument(
            "--dr-timeout-ms", type=int, default=100, help="time-out of each DR call, ms"
        )
        parser.add_argument(
            "--dr-retry-s",
            type=float,
            default=1.0,
            help="after the DR was missing or silent, ask again after this long, s",
        )

    @classmethod
    def prepare(cls, args: argparse.Namespace):
        given = [args.target_hue, args.target_saturation, args.target_diameter]
        target = None
        if any(v is not None for v in given):
            if any(v is None for v in given):
                raise ConfigError(
                    "--target-hue, --target-saturation and --target-diameter go together"
                )
            try:
                target = Target(*given).checked()
            except InvalidTarget as e:
                raise ConfigError(f"the target flags: {e}") from None
        if not 0.0 <= args.dr_update_confidence <= 1.0:
            raise ConfigError(f"--dr-update-confidence {args.dr_update_confidence} is not in [0, 1]")
        if not (math.isfinite(args.dr_retry_s) and args.dr_retry_s >= 0.0):
            raise ConfigError(f"--dr-retry-s {args.dr_retry_s} must be a finite time >= 0")
        if not (math.isfinite(args.detect_timeout_s) and args.detect_timeout_s >= 0.0):
            raise ConfigError(f"--detect-timeout-s {args.detect_timeout_s} must be a finite time >= 0")
        args.target = target
        return args

    def __init__(self, node, args) -> None:
        super().__init__(node, args)
        self.log = node.log
        self.every_frame = args.every_frame
        self.tracker = BallTracker(Config(detect_timeout_s=args.detect_timeout_s))
        self.tracker.set_target(args.target)
        if args.target is not None:
            t = args.target
            self.log.info(
                "looking for a ball of hue %.1f deg, saturation %.2f, diameter %.3f m",
                t.hue_deg,
                t.saturation,
                t.diameter_m,
            )
        #: Checked targets (stamp ns, target or None) given for frames not yet seen.
        self.pending_targets: collections.deque = collections.deque()
        self.dr = None
        if not args.no_dr:
            self.dr = DrLink(
                node,
                DrOptions(
                    robot_frame=args.robot_frame,
                    ball_node=args.ball_node,
                    timeout_s=max(args.dr_timeout_ms, 1) / 1000.0,
                    retry_s=args.dr_retry_s,
                    update_confidence=args.dr_update_confidence,
                ),
            )
        self.warn_limit = RateLimiter(1.0)
        #: The camera's sequence number of the last frame taken in.
        self.last_seq: int | None = None
        self.tracks = node.publisher("vision/ball", msg.BallTrack)
        self.events = node.publisher("vision/ball_events", msg.BallEvent)
        node.subscribe("vision/ball_target", msg.BallTarget, self.on_target, queue=16)
        # Offline evaluation (--every-frame) takes every frame in order; live, only the newest
        # waits while one is tracked.
        node.subscribe(
            "vision/rgbd",
            msg.RgbdFrame,
            self.on_frame,
            queue=256 if self.every_frame else 1,
            with_seq=True,
        )

    # -- targets -----------------------------------------------------------------------------

    def on_target(self, m: msg.BallTarget) -> None:
        try:
            target = (
                Target(m.hue_deg, m.saturation, m.diameter_m).checked() if m.active else None
            )
        except InvalidTarget as e:
            self.node.count("bad_targets")
            self.log.warning("ignored a target: invalid target: %s", e)
            return
        if target is not None:
            self.log.info(
                "new target: hue %.1f deg, saturation %.2f, diameter %.3f m",
                m.hue_deg,
                m.saturation,
                m.diameter_m,
            )
        else:
            self.log.info("target cleared: waiting")
        at = stamp_ns(m.header)
        if at == 0:
            self.pending_targets.clear()
            self.tracker.set_target(target)
            return
        if len(self.pending_targets) == PENDING_TARGETS:
            self.tracker.set_target(self.pending_targets.popleft()[1])
        self.pending_targets.append((at, target))

    def apply_targets_due(self, frame_ns: int) -> None:
        """Applies the pending targets due for a frame stamped `frame_ns`."""
        while self.pending_targets:
            at, target = self.pending_targets[0]
            ahead = at - frame_ns > TARGET_LEAD_NS
            if at > frame_ns and not ahead:
                break
            self.pending_targets.popleft()
            if ahead:
                self.node.count("targets_ahead_of_frames")
                self.log.warning(
                    "a target stamped more than 1 s after the frame applied at once: do the "
                    "clocks of the camera and the target's sender agree?"
                )
            self.tracker.set_target(target)

    # -- frames ------------------------------------------------------------------------------

    def on_frame(self, frame: msg.RgbdFrame, seq: int) -> None:
        """Counts the frames the camera sent since the last one taken in, and tracks this one."""
        if self.last_seq is not None and seq > self.last_seq + 1:
            self.node.count("skipped_frames", seq - self.last_seq - 1)
        self.last_seq = seq
        self.track(frame, seq)

    def track(self, frame: msg.RgbdFrame, seq: int) -> None:
        """Tracks one frame and publishes its track and events."""
        header = frame.header
        ns = stamp_ns(header)
        try:
            rgb, depth, k = frame_arrays(frame)
            self.apply_targets_due(ns)
            out = self.tracker.process(rgb, depth, k, ns * 1e-9)
        except InvalidFrame as e:
            self.node.count("bad_frames")
            suppressed = self.warn_limit.allow()
            if suppressed is not None:
                more = f" ({suppressed} more since the last)" if suppressed else ""
                self.log.warning("skipped a frame: malformed frame: %s%s", e, more)
            return
        track, events = self.messages(out, header, ns, seq)
        if self.dr is not None:
            self.dr.process(track, ns)
        self.tracks.publish(track)
        for e in events:
            self.log.info("ball %s (frame stamped %d ns)", e.kind, ns)
            self.events.publish(e)

    @staticmethod
    def messages(out: TrackOutput, header: msg.Header, ns: int, seq: int):
        """The track and events of one tracker output, stamped with the frame's stamp in its
        `frame_id`, carrying the frame's sequence number."""
        h = msg.Header(stamp=time_of(ns), frame_id=header.frame_id)
        track = msg.BallTrack(header=h, frame_seq=seq, state=out.state)
        if out.window is not None:
            track.found = True
            track.window = msg.PixelWindow(*out.window)
        if out.centre_px is not None:
            track.centre_px = [float(out.centre_px[0]), float(out.centre_px[1])]
        if out.centre_m is not None:
            track.has_centre_m = True
            track.centre_m = msg.Point(*out.centre_m)
        track.diameter_m = float(out.measured_diameter_m or 0.0)
        track.confidence = float(out.confidence)
        events = [
            msg.BallEvent(header=h, frame_seq=track.frame_seq, kind=kind, state=out.state)
            for kind in out.events
        ]
        return track, events

