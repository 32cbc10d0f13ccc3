"""Tests of the tracker's machine on rendered frames, and of the bus-side conversions (no bus).

    python -m unittest discover -s components/ball_tracker_py/tests
"""

from __future__ import annotations

import math
import unittest

import numpy as np
from robocog import msg

import robocog_ball_tracker as component
from robocog_ball_tracker import dr
from robocog_ball_tracker.tracker import (
    DETECTED,
    DETECTION_TIMED_OUT,
    LOST,
    OUT_OF_VIEW,
    TRACKING,
    WAITING,
    BallTracker,
    Config,
    Intrinsics,
    InvalidFrame,
    InvalidTarget,
    Target,
    equivalent_diameter_m,
)

K = Intrinsics(525.0, 525.0, 319.5, 239.5)
YELLOW = (230, 203, 34)
# The game's ball (hue 52 deg, saturation 0.85, 7 cm), as the Executive asks for it.
GAME_BALL = Target(51.7, 0.85, 0.07)


def render(centre, diameter=0.07, w=640, h=480, k=K, colour=YELLOW, wall_mm=2000):
    """A frame of a shaded sphere centred at `centre` (camera optical frame, m) before a grey
    wall: (rgb, depth_mm)."""
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    r = np.stack(((u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u)), axis=-1)
    rgb = np.full((h, w, 3), 110, np.uint8)
    depth = np.full((h, w), wall_mm, np.uint16)
    if centre is None:
        return rgb, depth
    c = np.asarray(centre, float)
    a = (r * r).sum(-1)
    b = r @ c
    disc = b * b - a * (c @ c - (diameter / 2) ** 2)
    hit = disc >= 0
    t = (b - np.sqrt(np.where(hit, disc, 0.0))) / a
    p = r * t[..., None]
    n = (p - c) / (diameter / 2)
    shade = np.clip(-(n * r / np.linalg.norm(r, axis=-1, keepdims=True)).sum(-1), 0.0, 1.0)
    shade = 0.5 + 0.5 * shade
    ball = (np.asarray(colour, float)[None, None, :] * shade[..., None]).round().astype(np.uint8)
    rgb[hit] = ball[hit]
    depth[hit] = np.round(t[hit] * 1000.0).astype(np.uint16)
    return rgb, depth


class TrackerTest(unittest.TestCase):
    def test_detects_and_tracks_a_still_ball_within_a_centimetre(self):
        t = BallTracker()
        t.set_target(GAME_BALL)
        truth = (0.05, -0.03, 0.6)
        rgb, depth = render(truth)
        for i in range(5):
            out = t.process(rgb, depth, K, 100.0 + i / 30)
            self.assertEqual(out.state, TRACKING, i)
            self.assertEqual(out.events, [DETECTED] if i == 0 else [], i)
            err = math.dist(out.centre_m, truth)
            self.assertLess(err, 0.01, f"frame {i}: {err} m")
            self.assertGreater(out.confidence, 0.5)
            self.assertAlmostEqual(out.measured_diameter_m, 0.07, delta=0.015)

    def test_follows_a_moving_ball_and_loses_it_at_the_border_after_out_of_view(self):
        t = BallTracker()
        t.set_target(GAME_BALL)
        events = []
        # 0.6 m away, moving right at 0.6 m/s until it leaves the image.
        for i in range(60):
            x = -0.1 + 0.02 * i
            out = t.process(*render((x, 0.0, 0.6)), K, 100.0 + i / 30)
            events += out.events
            if x < 0.3:
                self.assertEqual(out.state, TRACKING, i)
                self.assertLess(math.dist(out.centre_m, (x, 0.0, 0.6)), 0.015, i)
        self.assertEqual(events[0], DETECTED)
        self.assertEqual(events[1:3], [OUT_OF_VIEW, LOST], events)

    def test_a_ball_that_vanishes_mid_image_is_lost_without_out_of_view(self):
        t = BallTracker()
        t.set_target(GAME_BALL)
        t.process(*render((0.0, 0.0, 0.6)), K, 1.0)
        empty = render(None)
        events = []
        for i in range(5):
            events += t.process(*empty, K, 1.0 + (i + 1) / 30).events
        self.assertEqual(events, [LOST])

    def test_detection_times_out_back_to_waiting(self):
        t = BallTracker(Config(detect_timeout_s=1.0))
        t.set_target(GAME_BALL)
        empty = render(None)
        self.assertEqual(t.process(*empty, K, 10.0).events, [])
        out = t.process(*empty, K, 11.0)
        self.assertEqual((out.events, out.state), ([DETECTION_TIMED_OUT], WAITING))
        self.assertIsNone(t.target)

    def test_another_colour_or_size_is_not_the_ball(self):
        t = BallTracker()
        t.set_target(GAME_BALL)
        self.assertEqual(t.process(*render((0, 0, 0.6), colour=(30, 40, 220)), K, 1.0).events, [])
        self.assertEqual(t.process(*render((0, 0, 0.6), diameter=0.2), K, 2.0).events, [])

    def test_targets_and_frames_are_checked(self):
        t = BallTracker()
        self.assertEqual(Target(-10.0, 0.5, 0.1).checked().hue_deg, 350.0)
        for bad in (
            Target(10.0, 1.5, 0.1),
            Target(10.0, 0.5, 0.0),
            Target(float("nan"), 0.5, 0.1),
            Target(10.0, 0.5, float("inf")),
        ):
            with self.assertRaises(InvalidTarget):
                t.set_target(bad)
        self.assertEqual(t.state, WAITING)
        rgb, depth = render(None, w=8, h=6)
        with self.assertRaises(InvalidFrame):
            t.process(rgb, depth, Intrinsics(0.0, 525.0, 4.0, 3.0), 0.0)
        with self.assertRaises(InvalidFrame):
            t.process(rgb[:, :4], depth, K, 0.0)
        with self.assertRaises(InvalidFrame):
            t.process(rgb, depth, K, float("nan"))

    def test_equivalent_diameter_of_a_sphere_silhouette(self):
        f = 525.0
        r_px = f * 0.05 / math.sqrt(1.0 - 0.05 * 0.05)
        z_med = 1.0 - 0.05 * math.sqrt(0.5)
        self.assertAlmostEqual(equivalent_diameter_m(math.pi * r_px**2, z_med, f), 0.1, delta=0.001)
        self.assertIsNone(equivalent_diameter_m(0.0, 1.0, f))
        self.assertIsNone(equivalent_diameter_m(1e8, 1.0, f))


def frame_msg(rgb, depth, k=K, stamp_ns=1_700_000_000_123_456_789, frame_id="cam"):
    h, w = depth.shape
    header = msg.Header(stamp=component.time_of(stamp_ns), frame_id=frame_id)
    info = msg.CameraInfo(header=header, height=h, width=w)
    info.k = [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]
    return msg.RgbdFrame(
        header=header,
        camera_info=info,
        rgb=msg.Image(header, h, w, "rgb8", 0, w * 3, rgb.tobytes()),
        depth=msg.Image(header, h, w, "16UC1", 0, w * 2, depth.astype("<u2").tobytes()),
    )


class BusSideTest(unittest.TestCase):
    def test_frames_are_checked_before_use(self):
        rgb, depth = render(None, w=8, h=6)
        rgb_v, depth_v, k = component.frame_arrays(frame_msg(rgb, depth))
        self.assertEqual((rgb_v.shape, depth_v.shape, k), ((6, 8, 3), (6, 8), K))
        short = frame_msg(rgb, depth)
        short.depth.data = short.depth.data[:-2]
        no_focal = frame_msg(rgb, depth, k=Intrinsics(0.0, 0.0, 4.0, 3.0))
        empty = frame_msg(rgb[:0], depth[:0])
        other_size = frame_msg(rgb, depth)
        other_size.depth.width = 4
        for bad in (short, no_focal, empty, other_size):
            with self.assertRaises(InvalidFrame):
                component.frame_arrays(bad)

    def test_a_track_carries_the_frames_stamp_and_frame(self):
        t = BallTracker()
        t.set_target(GAME_BALL)
        f = frame_msg(*render((0.0, 0.0, 0.6)))
        rgb, depth, k = component.frame_arrays(f)
        ns = component.stamp_ns(f.header)
        out = t.process(rgb, depth, k, ns * 1e-9)
        track, events = component.BallTrackerComponent.messages(out, f.header, ns, 42)
        self.assertEqual(component.stamp_ns(track.header), 1_700_000_000_123_456_789)
        self.assertEqual(track.header.frame_id, "cam")
        self.assertEqual((track.state, track.found, track.has_centre_m), ("tracking", True, True))
        self.assertAlmostEqual(track.centre_m.z, 0.6, delta=0.01)
        self.assertEqual([(e.kind, e.state) for e in events], [("detected", "tracking")])
        self.assertEqual(events[0].header, track.header)

    def test_the_centre_goes_through_both_transforms(self):
        track = msg.BallTrack(found=True, has_centre_m=True, confidence=0.9)
        track.centre_m = msg.Point(0.1, -0.2, 1.0)
        # A camera 1.5 m up looking along world +x (optical z = world x, x = -y, y = -z).
        rot = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        q = _quaternion(rot)
        world = dr.isometry(msg.Transform(msg.Vector3(0.0, 0.0, 1.5), msg.Quaternion(*q)))
        robot = dr.isometry(msg.Transform(msg.Vector3(-1.0, 0.0, 1.5), msg.Quaternion(*q)))
        dr.locate(track, world, robot)
        self.assertTrue(track.has_centre_world)
        w, r = track.centre_world_m, track.centre_robot_m
        np.testing.assert_allclose((w.x, w.y, w.z), (1.0, -0.1, 1.7), atol=1e-12)
        np.testing.assert_allclose((r.x, r.y, r.z), (0.0, -0.1, 1.7), atol=1e-12)
        self.assertTrue(dr.should_update(track, 0.5))
        self.assertFalse(dr.should_update(track, 0.95))
        bad = msg.Transform(msg.Vector3(float("nan"), 0.0, 0.0), msg.Quaternion(0.0, 0.0, 0.0, 1.0))
        self.assertIsNone(dr.isometry(bad))
        # A zero quaternion is no rotation; the default one is the identity (as in ROS 2).
        self.assertIsNone(dr.isometry(msg.Transform(rotation=msg.Quaternion(0.0, 0.0, 0.0, 0.0))))
        rot, t = dr.isometry(msg.Transform())
        np.testing.assert_allclose(rot, np.eye(3))


def _quaternion(m):
    """(x, y, z, w) of a rotation matrix with a positive trace."""
    w = math.sqrt(1.0 + m[0, 0] + m[1, 1] + m[2, 2]) / 2.0
    return (
        (m[2, 1] - m[1, 2]) / (4 * w),
        (m[0, 2] - m[2, 0]) / (4 * w),
        (m[1, 0] - m[0, 1]) / (4 * w),
        w,
    )


if __name__ == "__main__":
    unittest.main()
