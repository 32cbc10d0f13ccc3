"""A Python component for the suite (tests/tests/python.rs): answers on the bus as the tests ask.

- `py/in` (Text): publishes the text upper-cased on `py/out`; "boom" raises in the callback;
  "starts" answers how many times the component started with this state folder.
- `py/upper` (Text -> Text): the text upper-cased; an empty text is refused (BadRequest).
- with `--frames`: for each of the first frames on `vision/rgbd`, a report on `py/out` (JSON) of
  what the NumPy views of its images are: shape, whether they own or borrow their memory, and
  whether that memory is the sample's shared-memory buffer.
"""

import json
import os

import robocog
from robocog import images, msg
from robocog.component import Component, ConfigError


class Fixture(Component):
    NAME = "py_fixture"
    ABOUT = "a Python component the suite talks to"
    SUBSCRIBES = [("py/in", msg.Text)]
    PUBLISHES = [("py/out", msg.Text)]
    SERVES = [("py/upper", msg.Text, msg.Text)]

    @classmethod
    def add_arguments(cls, parser):
        parser.add_argument("--frames", action="store_true", help="report on vision/rgbd frames")
        parser.add_argument("--prefix", default="", help="put before every answer")

    @classmethod
    def prepare(cls, args):
        if "/" in args.prefix:
            raise ConfigError(f"--prefix {args.prefix!r}: no slashes")
        return args

    def __init__(self, node, args):
        super().__init__(node, args)
        self.prefix = args.prefix
        self.out = node.publisher("py/out", msg.Text)
        node.subscribe("py/in", msg.Text, self.on_text)
        node.serve("py/upper", msg.Text, msg.Text, self.upper)
        self.reported = 0
        # How many times it started, kept in its state folder across restarts.
        self.starts = 1
        if node.state_dir is not None:
            path = node.state_dir / "starts"
            if path.exists():
                self.starts = int(path.read_text()) + 1
            tmp = path.with_suffix(".tmp")
            tmp.write_text(str(self.starts))
            os.replace(tmp, path)
        if args.frames:
            node.subscribe("vision/rgbd", msg.RgbdFrame, self.on_frame, queue=2)

    def on_text(self, m):
        if m.text == "boom":
            raise RuntimeError("boom, as asked")
        if m.text == "starts":
            self.out.publish(msg.Text(text=f"STARTS {self.starts}"))
            return
        self.out.publish(msg.Text(text=self.prefix + m.text.upper()))

    def upper(self, req):
        if not req.text:
            raise robocog.ServiceError("BadRequest", "nothing to upper-case")
        return msg.Text(text=req.text.upper())

    def on_frame(self, frame):
        if self.reported >= 3:
            return
        self.reported += 1
        rgb = images.rgb(frame)
        depth = images.depth_mm(frame)
        # NumPy keeps the buffer's owner as the arrays' base: the received sample itself.
        sample = rgb.base
        report = {
            "rgb_shape": list(rgb.shape),
            "depth_shape": list(depth.shape),
            "owns_pixels": bool(rgb.flags.owndata or depth.flags.owndata),
            "writeable": bool(rgb.flags.writeable),
            "same_sample": depth.base is sample,
            "shm": bool(sample.is_shm),
            "depth_max_mm": int(depth.max()),
            "width": frame.rgb.width,
            "stamp_ns": frame.header.stamp.sec * 1_000_000_000 + frame.header.stamp.nanosec,
        }
        self.out.publish(msg.Text(text=json.dumps(report)))
