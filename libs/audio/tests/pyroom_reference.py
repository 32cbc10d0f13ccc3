"""pyroomacoustics' room impulse responses for the set-ups the audio crate's image-source room
is checked against (tests/room_reference.rs).

Usage: python pyroom_reference.py SETUPS.json OUT.json

SETUPS.json: {"setups": [{"dims_m", "rt60_s", "absorption", "max_order", "source_m", "mic_m",
"rate_hz"}, ...]}. For each set-up, OUT.json gets pyroomacoustics' own inversion of Sabine's
formula for (dims_m, rt60_s) and the impulse responses of a ShoeBox with the given absorption and
max_order, image sources only (no air absorption, no ray tracing): "rir" as compute_rir() makes
it by default (high-passed), "image_rir" with that high-pass turned off. The versions and the
speed of sound used come along, so that the test can say what it compared with.
"""

import json
import sys

import numpy as np
import pyroomacoustics as pra
import scipy


def impulse_response(setup, high_pass):
    pra.constants.set("rir_hpf_enable", high_pass)
    room = pra.ShoeBox(
        setup["dims_m"],
        fs=int(setup["rate_hz"]),
        materials=pra.Material(setup["absorption"]),
        max_order=setup["max_order"],
        air_absorption=False,
        ray_tracing=False,
    )
    room.add_source(setup["source_m"])
    room.add_microphone_array(np.array([setup["mic_m"]], dtype=float).T)
    room.compute_rir()
    return room.c, [float(v) for v in room.rir[0][0]]


def main():
    with open(sys.argv[1], encoding="utf-8") as f:
        setups = json.load(f)["setups"]
    out = {
        "pyroomacoustics": pra.__version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "frac_delay_length": pra.constants.get("frac_delay_length"),
        "rir_hpf_fc": pra.constants.get("rir_hpf_fc"),
        "setups": [],
    }
    for setup in setups:
        absorption, max_order = pra.inverse_sabine(setup["rt60_s"], setup["dims_m"])
        c, rir = impulse_response(setup, high_pass=True)
        _, image_rir = impulse_response(setup, high_pass=False)
        out["setups"].append(
            {
                "absorption": float(absorption),
                "max_order": int(max_order),
                "c": float(c),
                "rir": rir,
                "image_rir": image_rir,
            }
        )
    with open(sys.argv[2], "w", encoding="utf-8") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main()
