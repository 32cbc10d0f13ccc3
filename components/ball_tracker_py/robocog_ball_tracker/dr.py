"""The ball in the world and the robot frames, through the deep representation (DR): what
`components/ball_tracker/src/dr.rs` does, with the same requests.

For each track with a centre in the camera frame, `dr/transform` is asked for `world_T_camera`
and `robot_T_camera` (`robot`: `base_footprint` by default) at the frame's stamp, and the
track's `centre_world_m` and `centre_robot_m` are filled. A confident track (`confidence` at
least `update_confidence`) then writes the ball node's pose (`dr/update`: a `PoseUpdate` of
`ball_node`, parent `world`, at the frame's stamp).

The DR missing or silent (past `timeout_s`): the track stays in the camera frame
(`has_centre_world = False`), counted (`dr_unavailable`), logged at most once a second, and the
DR is not asked again for `retry_s` (on the node's clock). An error answer costs that one track
its world position (`dr_transform_errors`). Updates are counted (`dr_updates`,
`dr_update_errors`).

The calls are made on the callback thread, one after the other (the Python API has no
asynchronous call): each waits at most `timeout_s`, and a DR that does not answer is given up
for `retry_s`, so a missing DR costs one time-out a second at most.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import robocog
from robocog import msg

from .ratelimit import RateLimiter


@dataclasses.dataclass
class DrOptions:
    robot_frame: str = "base_footprint"
    ball_node: str = "ball"
    timeout_s: float = 0.1
    retry_s: float = 1.0
    update_confidence: float = 0.5


def isometry(t: msg.Transform):
    """`target_T_source` of a DR transform as (3x3 rotation, translation), or None when its
    numbers are unusable (not finite, a quaternion far from unit)."""
    x, y, z = t.translation.x, t.translation.y, t.translation.z
    q = t.rotation
    qx, qy, qz, qw = q.x, q.y, q.z, q.w
    values = (x, y, z, qx, qy, qz, qw)
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        return None
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if not 0.5 < n < 1.5:
        return None
    qx, qy, qz, qw = qx / n, qy / n, qz / n, qw / n
    rot = np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )
    return rot, np.array([x, y, z], dtype=float)


def locate(track: msg.BallTrack, world_t_camera, robot_t_camera) -> None:
    """Fills the track's world and robot positions from its camera-frame centre."""
    if not track.has_centre_m:
        return
    c = np.array([track.centre_m.x, track.centre_m.y, track.centre_m.z])
    w = world_t_camera[0] @ c + world_t_camera[1]
    r = robot_t_camera[0] @ c + robot_t_camera[1]
    track.has_centre_world = True
    track.centre_world_m = msg.Point(float(w[0]), float(w[1]), float(w[2]))
    track.centre_robot_m = msg.Point(float(r[0]), float(r[1]), float(r[2]))


def should_update(track: msg.BallTrack, min_confidence: float) -> bool:
    """Whether a located track is good enough to move the DR's ball node."""
    return track.found and track.has_centre_world and track.confidence >= min_confidence


class DrLink:
    """The tracker's DR client: see the module doc."""

    def __init__(self, node: robocog.Node, options: DrOptions):
        self.node = node
        self.options = options
        self._resting_until_ns: int | None = None
        self._warn = RateLimiter(1.0)
        self._update_warn = RateLimiter(1.0)

    def warn(self, limiter: RateLimiter, text: str) -> None:
        suppressed = limiter.allow()
        if suppressed is not None:
            more = f" ({suppressed} more since the last)" if suppressed else ""
            self.node.log.warning("%s%s", text, more)

    def _transform(self, target: str, source: str, stamp_ns: int) -> msg.Transform:
        req = msg.TransformRequest(target=target, source=source, stamp_ns=max(stamp_ns, 1))
        reply = self.node.call("dr/transform", req, msg.TransformReply, self.options.timeout_s)
        return reply.transform

    def process(self, track: msg.BallTrack, stamp_ns: int) -> None:
        """Fills the world and robot positions of `track` (stamped `stamp_ns`) when it has a
        centre and the DR can tell, then updates the ball node when the track is confident."""
        if not track.has_centre_m:
            return
        node = self.node
        if self._resting_until_ns is not None:
            if node.now_ns() < self._resting_until_ns:
                node.count("dr_unavailable")
                return
            self._resting_until_ns = None
        frame = track.header.frame_id
        try:
            world = self._transform("world", frame, stamp_ns)
            robot = self._transform(self.options.robot_frame, frame, stamp_ns)
        except (robocog.NoServerError, TimeoutError, RuntimeError) as e:
            # Missing, silent, or the bus itself failing: rest, then ask again.
            node.count("dr_unavailable")
            self._resting_until_ns = node.now_ns() + int(self.options.retry_s * 1e9)
            self.warn(
                self._warn,
                f"no deep representation ({e}): publishing the ball in the camera frame only, "
                f"asking again in {self.options.retry_s:.1f} s",
            )
            return
        except (robocog.RemoteError, ValueError) as e:
            node.count("dr_transform_errors")
            self.warn(
                self._warn,
                f"the DR cannot place {frame} at {stamp_ns} ns ({e}): this track has no world "
                "position",
            )
        else:
            w, r = isometry(world), isometry(robot)
            if w is not None and r is not None:
                locate(track, w, r)
            else:
                node.count("dr_transform_errors")
                self.warn(
                    self._warn,
                    f"the DR gave a transform that is not a rigid motion for {frame} at "
                    f"{stamp_ns} ns",
                )
        if should_update(track, self.options.update_confidence):
            self._update(track, stamp_ns)

    def _update(self, track: msg.BallTrack, stamp_ns: int) -> None:
        """Writes the ball node's pose in `world` at the frame's stamp."""
        p = track.centre_world_m
        req = msg.UpdateRequest(
            header=msg.Header(
                stamp=msg.Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000),
                frame_id="world",
            ),
            poses=[
                msg.PoseUpdate(
                    node=self.options.ball_node,
                    pose=msg.Transform(
                        translation=msg.Vector3(p.x, p.y, p.z),
                        rotation=msg.Quaternion(0.0, 0.0, 0.0, 1.0),
                    ),
                )
            ],
        )
        try:
            self.node.call("dr/update", req, msg.UpdateReply, self.options.timeout_s)
        except (robocog.RemoteError, robocog.NoServerError, TimeoutError, RuntimeError, ValueError) as e:
            self.node.count("dr_update_errors")
            self.warn(self._update_warn, f"could not update the DR's `{self.options.ball_node}`: {e}")
        else:
            self.node.count("dr_updates")
