#!/usr/bin/python3 -s
"""Copies an rviz config and adds the test-only DisplayStatusProbe panel to it.

usage: add_status_probe.py IN.rviz OUT.rviz

Nothing else changes: the displays, view and window under test are the config's own.
"""
import sys

import yaml


def main():
    source, target = sys.argv[1:3]
    with open(source) as stream:
        config = yaml.safe_load(stream)
    config.setdefault("Panels", []).append(
        {"Class": "lidar_deskew_test/DisplayStatusProbe", "Name": "Display Status Probe"})
    with open(target, "w") as stream:
        yaml.safe_dump(config, stream, default_flow_style=False, sort_keys=False)


if __name__ == "__main__":
    main()
