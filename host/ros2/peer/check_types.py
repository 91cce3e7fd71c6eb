"""Checks Ferrobot's ROS 2 message definitions and their RIHS01 type hashes with rosbags.

Usage: check_types.py TYPES.json

TYPES.json lists, for each type Ferrobot speaks, its name (pkg/msg/Type), its MCAP `ros2msg`
schema (its definition and every type it uses) and the RIHS01 hash Ferrobot computed. For each:

- a type ROS 2 Jazzy defines must have, in rosbags' own Jazzy type store (ROS's definitions,
  not ours), the hash Ferrobot computed;
- every type, parsed by rosbags from Ferrobot's own schema text into an empty store, must hash
  the same (our text says what we think it says).

Prints one line per type and exits 1 on any disagreement.
"""

import json
import sys

from rosbags.typesys import Stores, get_typestore, get_types_from_msg


def parse_schema(name, schema):
    """The types of a rosbag2-style schema: the definition, then `MSG: pkg/Type` sections."""
    sep = "=" * 80 + "\n"
    parts = schema.split(sep)
    types = get_types_from_msg(parts[0], name)
    for part in parts[1:]:
        head, _, text = part.partition("\n")
        assert head.startswith("MSG: "), head
        pkg, typ = head[len("MSG: "):].split("/")
        types.update(get_types_from_msg(text, f"{pkg}/msg/{typ}"))
    return types


def main():
    entries = json.load(open(sys.argv[1]))
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    bad = 0
    for e in entries:
        name, ours = e["name"], e["rihs01"]
        theirs = jazzy.hash_rihs01(name) if name in jazzy.fielddefs else None
        own = get_typestore(Stores.EMPTY)
        own.register(parse_schema(name, e["schema"]))
        from_text = own.hash_rihs01(name)
        ok = from_text == ours and theirs in (None, ours)
        bad += not ok
        print(f"{'ok ' if ok else 'BAD'} {name}: ours {ours}, rosbags' Jazzy {theirs}, "
              f"rosbags from our text {from_text}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
