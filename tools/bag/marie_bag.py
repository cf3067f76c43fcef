#!/usr/bin/env python3
"""marie bag: LCM logs <-> ROS 2 bags (rosbag2: MCAP or sqlite3 storage, CDR messages), with the
conversions of marie-ros2 (docs/ros2.md). Runs in the venv scripts/bag-venv.sh makes.

  marie bag export LOG.lcm OUT [--map CHANNEL=TOPIC]... [--only CHANNEL]... [--all] [--storage mcap|sqlite3]
  marie bag import BAG OUT.lcm [--map TOPIC=CHANNEL]...     (BAG: a rosbag2 folder, .mcap or .db3)
  marie bag info PATH                                     (a rosbag2 bag or an LCM log)
  common: [--types DIR]...                                 (a user's types, as MARIE_TYPES_PATH)

Export writes the channels that config/spartacus.yaml's `ros2:` table names (or --map adds, or
--all: every channel), plus /tf from odometry (odom -> base_link) and poses (map -> odom). A type
with no ROS 2 counterpart (a user's, made by marie-types-gen: MARIE_TYPES_PATH or --types) goes
as a custom message PKG_msgs/msg/Name whose definition the bag holds (docs/ros2.md). Import reads
every topic of a type marie has, onto the channel the table gives it (or --map, else the topic's
name in capitals: /front/scan -> FRONT_SCAN). Malformed messages are counted and left out.
Exit status: 0, 1 on failure, 2 on usage.
"""
import argparse
import sys


def main():
    import marie                # marie's Python package: its version, and no third-party module
    ap = argparse.ArgumentParser(prog="marie bag", description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--version", action="version", version="marie-bag (marie %s)" % marie.__version__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("export", help="LCM log -> rosbag2")
    e.add_argument("log")
    e.add_argument("out")
    e.add_argument("--map", action="append", metavar="CHANNEL=TOPIC")
    e.add_argument("--only", action="append", metavar="CHANNEL")
    e.add_argument("--all", action="store_true", help="every channel of a known type (topic: /channel_in_lower_case)")
    e.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    e.add_argument("--force", action="store_true")
    i = sub.add_parser("import", help="rosbag2 (MCAP or sqlite3) -> LCM log")
    i.add_argument("bag")
    i.add_argument("out")
    i.add_argument("--map", action="append", metavar="TOPIC=CHANNEL")
    i.add_argument("--force", action="store_true")
    n = sub.add_parser("info", help="what a bag or an LCM log holds")
    n.add_argument("path")
    for p in (e, i, n):
        p.add_argument("--types", action="append", metavar="DIR", help="a user's types (marie-types-gen -o DIR)")
    args = ap.parse_args()
    import bag_ops              # rosbags, numpy and LCM: only once the command line is read
    try:
        return {"export": bag_ops.export, "import": bag_ops.import_, "info": bag_ops.info}[args.cmd](args)
    except (OSError, ValueError, KeyError) as ex:
        print("marie bag: %s" % ex, file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
