"""RIHS01 type hashes (REP 2011) computed by `rosbags`, an implementation independent of
robocog's: reads a JSON list of {"ros2": name, "definition": full definition} from the file
given, prints a JSON object {name: hash}."""

import json
import sys

from rosbags.typesys import Stores, get_typestore

from decode import register


def main(path):
    out = {}
    for t in json.load(open(path)):
        store = get_typestore(Stores.EMPTY)
        register(store, t["ros2"], t["definition"])
        out[t["ros2"]] = store.hash_rihs01(t["ros2"])
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
