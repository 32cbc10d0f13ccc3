"""A ROS 2 node as rmw_zenoh puts one on zenoh, without ROS 2: the eclipse-zenoh client from
PyPI, following rmw_zenoh's documented formats (docs/design.md of ros2/rmw_zenoh), and rosbags
for the CDR. Used by tests/tests/ros2.rs against robocog's ros2_bridge.

1. Lists the ROS 2 graph from its liveliness tokens (what `ros2 topic list` reads).
2. Subscribes to --listen's data key and decodes what arrives with the ROS 2 definition given.
3. Publishes on --publish as a ROS 2 publisher would (node and publisher tokens, samples with
   rmw_zenoh's attachment), then a sample without an attachment, one with a short attachment,
   one whose payload does not decode, one on a key with another type hash, and announces a
   publisher of a type robocog does not know.

Prints one JSON object.
"""

import argparse
import json
import struct
import sys
import time

import zenoh
from rosbags.typesys import Stores, get_typestore

from decode import register

QOS = "::,10:,:,:,,"


def dds(ros_name):
    pkg, name = ros_name.split("/msg/")
    return f"{pkg}::msg::dds_::{name}_"


def attachment(seq, gid):
    return struct.pack("<qq", seq, time.time_ns()) + bytes([16]) + gid


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", required=True)
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--ros-name", required=True, help="robocog_msgs/msg/Text")
    ap.add_argument("--hash", required=True)
    ap.add_argument("--definition", required=True, help="a file with the full definition")
    ap.add_argument("--listen", required=True, help="a ROS 2 topic robocog publishes: /chatter")
    ap.add_argument("--publish", required=True, help="a ROS 2 topic to publish on: /ros_said")
    ap.add_argument("--count", type=int, default=3)
    ap.add_argument(
        "--ready-token",
        required=True,
        help="the liveliness token that says the bridge takes --publish in",
    )
    a = ap.parse_args()

    store = get_typestore(Stores.EMPTY)
    register(store, a.ros_name, open(a.definition).read())
    Text = store.types[a.ros_name]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]

    def now():
        ns = time.time_ns()
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([a.connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    out = {"zid": str(session.zid())}

    # 1. The graph, as ROS 2 sees it.
    listen_type = dds(a.ros_name)
    want = f"/{a.listen.strip('/')}".replace("/", "%")
    tokens = []
    deadline = time.time() + 20
    while time.time() < deadline:
        tokens = [
            str(r.ok.key_expr)
            for r in session.liveliness().get(f"@ros2_lv/{a.domain}/**", timeout=2.0)
            if r.ok is not None
        ]
        if any(f"/MP/%/%/" in t and f"/{want}/{listen_type}/" in t for t in tokens):
            break
        time.sleep(0.2)
    out["tokens"] = tokens

    # 2. A robocog topic, read as a ROS 2 subscriber reads it.
    key = f"{a.domain}/{a.listen.strip('/')}/{listen_type}/{a.hash}"
    received = []
    sub = session.declare_subscriber(key)
    deadline = time.time() + 20
    while len(received) < a.count and time.time() < deadline:
        s = sub.try_recv()
        if s is None:
            time.sleep(0.02)
            continue
        att = bytes(s.attachment.to_bytes()) if s.attachment is not None else b""
        msg = store.deserialize_cdr(bytes(s.payload.to_bytes()), a.ros_name)
        entry = {"key": str(s.key_expr), "text": msg.text, "attachment_len": len(att)}
        if len(att) == 33 and att[16] == 16:
            seq, ts = struct.unpack("<qq", att[:16])
            entry.update(seq=seq, source_ns=ts, gid=att[17:].hex())
        received.append(entry)
    sub.undeclare()
    out["received"] = received

    # 3. A ROS 2 publisher feeding robocog.
    zid = str(session.zid())
    node_token = f"@ros2_lv/{a.domain}/{zid}/0/0/NN/%/%/pytalker"
    topic = a.publish.strip("/")
    pub_token = (
        f"@ros2_lv/{a.domain}/{zid}/0/1/MP/%/%/pytalker/%{topic.replace('/', '%')}"
        f"/{dds(a.ros_name)}/{a.hash}/{QOS}"
    )
    gid = bytes(range(16))
    t1 = session.liveliness().declare_token(node_token)
    t2 = session.liveliness().declare_token(pub_token)
    other_token = (
        f"@ros2_lv/{a.domain}/{zid}/0/2/MP/%/%/pytalker/%ros_other"
        f"/std_msgs::msg::dds_::String_/RIHS01_{'0' * 64}/{QOS}"
    )
    t3 = session.liveliness().declare_token(other_token)
    data_key = f"{a.domain}/{topic}/{dds(a.ros_name)}/{a.hash}"
    pub = session.declare_publisher(data_key)
    # The bridge heard the tokens and subscribed: its robocog publisher is announced after.
    deadline = time.time() + 20
    while time.time() < deadline:
        if any(r.ok is not None for r in session.liveliness().get(a.ready_token, timeout=1.0)):
            break
        time.sleep(0.05)
    else:
        raise SystemExit(f"the bridge never took {a.publish} in ({a.ready_token})")
    sent = []
    for i in range(1, a.count + 1):
        text = f"from ros {i}"
        msg = Text(header=Header(stamp=now(), frame_id=""), text=text)
        pub.put(bytes(store.serialize_cdr(msg, a.ros_name)), attachment=attachment(i, gid))
        sent.append(text)
        time.sleep(0.1)
    good = bytes(
        store.serialize_cdr(
            Text(header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""), text="bad"), a.ros_name
        )
    )
    pub.put(good)  # no attachment
    pub.put(good, attachment=attachment(99, gid)[:20])  # a short attachment
    pub.put(b"\x00\x01\x00\x00\xff\xff\xff\x7f", attachment=attachment(100, gid))  # undecodable
    session.put(
        f"{a.domain}/{topic}/{dds(a.ros_name)}/RIHS01_{'1' * 64}",
        good,
        attachment=attachment(101, gid),
    )  # another type hash
    time.sleep(1.0)
    out["sent"] = sent
    for t in (t3, t2, t1):
        t.undeclare()
    pub.undeclare()
    session.close()
    print(json.dumps(out))


if __name__ == "__main__":
    sys.exit(main())
