"""Decode every message of an MCAP recording with ROS 2 decoders from PyPI, as a tool outside
robocog would: `mcap-ros2-support` (what Foxglove's Python tooling uses) reads each `ros2msg`
channel from its schema alone, and `rosbags` registers the same definitions over ROS 2 Jazzy's
own standard messages (a standard message defined otherwise is an error) and serializes the
decoded message again, which must give back the recorded bytes exactly.

Prints one JSON line per message, in file order:
  {"topic", "schema", "encoding", "decoded": {...}, "same_bytes": bool}
or, for a channel whose schema is not ros2msg, {"topic", "schema", "encoding", "skipped": true};
and for a message a decoder refused, {"topic", "schema", "error": "..."}.
Long byte sequences are summarized as {"bytes": n, "fnv1a64": "..."} (robocog's side does the
same) so the output stays small.
"""

import json
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

SEPARATOR = "=" * 80
LONG = 64


def fnv1a64(data):
    h = 0xCBF29CE484222325
    for b in data:
        h ^= b
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return format(h, "016x")


def plain(v):
    """A decoded value as plain JSON data."""
    if isinstance(v, (bytes, bytearray, memoryview)):
        v = list(bytes(v))
        if len(v) > LONG:
            return {"bytes": len(v), "fnv1a64": fnv1a64(v)}
        return v
    if hasattr(v, "tolist"):
        return plain(v.tolist())
    if isinstance(v, (list, tuple)):
        items = [plain(x) for x in v]
        if len(items) > LONG and all(type(x) is int and 0 <= x < 256 for x in items):
            return {"bytes": len(items), "fnv1a64": fnv1a64(items)}
        return items
    if isinstance(v, float) and v != v:
        return None
    if hasattr(v, "__slots__"):
        return {k: plain(getattr(v, k)) for k in v.__slots__ if not k.startswith("_")}
    return v


def register(store, schema_name, text):
    """Register a full definition (the type, then its dependencies after separator lines)."""
    parts = text.split(SEPARATOR)
    types = {}
    types.update(get_types_from_msg(parts[0], schema_name))
    for part in parts[1:]:
        part = part.strip("\n")
        first, _, body = part.partition("\n")
        assert first.startswith("MSG: "), first
        name = first[len("MSG: "):].strip()
        if "/msg/" not in name:
            pkg, _, typ = name.partition("/")
            name = f"{pkg}/msg/{typ}"
        types.update(get_types_from_msg(body, name))
    store.register(types)


def main(path):
    store = get_typestore(Stores.ROS2_JAZZY)
    registered = set()
    out = sys.stdout
    factory = DecoderFactory()
    decoders = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            line = {
                "topic": channel.topic,
                "schema": schema.name if schema else None,
                "encoding": schema.encoding if schema else None,
            }
            if schema is None or schema.encoding != "ros2msg":
                line["skipped"] = True
                out.write(json.dumps(line) + "\n")
                continue
            try:
                if schema.id not in decoders:
                    decoders[schema.id] = factory.decoder_for(channel.message_encoding, schema)
                if schema.name not in registered:
                    register(store, schema.name, schema.data.decode())
                    registered.add(schema.name)
                value = decoders[schema.id](message.data)
                line["decoded"] = plain(value)
                again = store.serialize_cdr(
                    store.deserialize_cdr(message.data, schema.name), schema.name
                )
                line["same_bytes"] = bytes(again) == bytes(message.data)
            except Exception as e:  # a refusal is reported, not fatal: the test counts it
                line["error"] = f"{type(e).__name__}: {e}"
            out.write(json.dumps(line) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
