"""Every message type through Python and back (tests/tests/python.rs): a value with every field
set (not the defaults) is encoded by the Rust encoder from the Python object, decoded into the
generated class, and must come back equal, and encode to the same bytes again. A value of the
wrong type is refused with a message naming the type. Prints one line per type; exits 1 when
any differs.

Some wire forms are tagged unions laid flat (a `kind` and the fields of every variant: the DR's
attribute values, edges, shapes, changes): the fields of the variants the kind does not name are
zero once through the Rust type. For the types that hold one ([`FLAT_UNIONS`]), the first pass
may change the value, the second must not."""

import dataclasses
import sys
import typing

import robocog
from robocog import msg

HINTS = {}


def sample(hint, depth=0):
    """A value of `hint` (a type hint of robocog.msg) with something in it."""
    if isinstance(hint, str):
        hint = eval(hint, vars(msg))  # the generated module's own names
    origin = typing.get_origin(hint)
    if hint is int:
        return 7
    if hint is float:
        return 1.5
    if hint is str:
        return "x"
    if hint is bool:
        return True
    if hint is bytes:
        return b"ab"
    if origin is typing.Literal:
        return typing.get_args(hint)[-1]
    if origin is list:
        (inner,) = typing.get_args(hint)
        return [sample(inner, depth + 1)]
    if dataclasses.is_dataclass(hint):
        fields = typing.get_type_hints(hint, vars(msg))
        return hint(**{name: sample(t, depth + 1) for name, t in fields.items()})
    raise TypeError(f"no sample for {hint!r}")


def fixed_lengths(value, default):
    """Make fixed-size arrays (lists whose default has a length) the length their default has."""
    if dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            v, d = getattr(value, f.name), getattr(default, f.name)
            if isinstance(d, list) and d and isinstance(v, list):
                setattr(value, f.name, (v * len(d))[: len(d)])
            else:
                fixed_lengths(v, d)
    return value


FLAT_UNIONS = {
    "robocog.dr.DrChange",
    "robocog.dr.ForkRequest",
    "robocog.dr.NodeInfo",
    "robocog.dr.ProposeRequest",
    "robocog.dr.SnapshotData",
    "robocog.dr.UpdateRequest",
}


def frame():
    """A 2x2 RGB-D frame whose images fill their data, as the Rust type checks."""
    f = msg.RgbdFrame()
    f.header.stamp.sec, f.header.frame_id = 3, "camera"
    f.camera_info.width, f.camera_info.height = 2, 2
    f.camera_info.k = [500.0, 0.0, 1.0, 0.0, 500.0, 1.0, 0.0, 0.0, 1.0]
    # What the Rust type writes from its intrinsics: no distortion, identity R, P = [K | 0].
    f.camera_info.distortion_model, f.camera_info.d = "plumb_bob", [0.0] * 5
    f.camera_info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    f.camera_info.p = [500.0, 0.0, 1.0, 0.0, 0.0, 500.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    f.rgb = msg.Image(height=2, width=2, encoding="rgb8", step=6, data=bytes(range(12)))
    f.depth = msg.Image(height=2, width=2, encoding="16UC1", step=4, data=bytes(range(8)))
    f.rgb.header = f.depth.header = f.camera_info.header = f.header
    return f


failures = 0
for name, cls in sorted(msg.TYPES.items()):
    value = frame() if cls is msg.RgbdFrame else fixed_lengths(sample(cls), cls())
    try:
        payload = robocog.encode(value)
    except ValueError as e:
        # The Rust type refuses what no sender could mean (an image whose data does not fill
        # it): its reason names the type, and the defaults go through instead.
        if name not in str(e):
            print(f"FAIL {name}: the refusal does not name the type: {e}")
            failures += 1
            continue
        value = cls()
        payload = robocog.encode(value)
    back = robocog.decode(name, payload)
    if name in FLAT_UNIONS:
        value, payload = back, robocog.encode(back)
        back = robocog.decode(name, payload)
    if back != value:
        print(f"FAIL {name}: came back different\n  sent {value}\n  got  {back}")
        failures += 1
        continue
    again = robocog.encode(back)
    if again != payload:
        print(f"FAIL {name}: encoded again to other bytes")
        failures += 1
        continue
    print(f"ok {name} ({len(payload)} bytes)")

# Bad input: a wrong field type, and a payload that is not the type.
try:
    robocog.encode(msg.Text(text=3))
    print("FAIL an int where text goes was encoded")
    failures += 1
except ValueError as e:
    print(f"ok refused: {e}")
try:
    robocog.decode(msg.Text, b"\x00\x01\x00\x00\xff")
    print("FAIL a truncated payload was decoded")
    failures += 1
except ValueError as e:
    print(f"ok refused: {e}")
sys.exit(1 if failures else 0)
