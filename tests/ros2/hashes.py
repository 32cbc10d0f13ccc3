"""RIHS01 type hashes (REP 2011) computed by `rosbags`, an implementation independent of
robocog's. Reads a JSON object from the file given:
  {"robocog": [{"ros2": name, "definition": full definition}, ...], "standard": [name, ...]}
and prints a JSON object {name: hash}: robocog's types registered from their definitions (over
ROS 2 Jazzy's own standard messages, which must agree), and the standard messages as Jazzy
defines them."""

import json
import sys

from rosbags.typesys import Stores, get_typestore

from decode import register


def main(path):
    spec = json.load(open(path))
    out = {}
    for t in spec["robocog"]:
        store = get_typestore(Stores.ROS2_JAZZY)
        register(store, t["ros2"], t["definition"])
        out[t["ros2"]] = store.hash_rihs01(t["ros2"])
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    for name in spec["standard"]:
        out[name] = jazzy.hash_rihs01(name)
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
