#!/usr/bin/env python3
"""Every dependency key of package.xml resolves for ROS Noetic on Ubuntu 20.04 (focal), so that
`rosdep install --from-paths src -y` installs what the build and the tests need (docs/PACKAGING.md).

A key resolves when a package of that name is released in rosdistro's noetic/distribution.yaml (and is
not end-of-life there), or when rosdep/base.yaml or rosdep/python.yaml names Ubuntu focal packages for it.

With --rosdistro DIR, $LIDAR_DESKEW_ROSDISTRO or ../shared/data/rosdistro beside the repo (a snapshot of ros/rosdistro: DIR/rosdep/base.yaml, DIR/rosdep/python.yaml,
DIR/noetic/distribution.yaml) every key is resolved in those files, and KNOWN below is checked against
them. Without one, every key must be in KNOWN: what these files said for our keys when we last looked
(a key added to package.xml fails here until it is checked against a snapshot and added).

Usage: check_rosdep_keys.py PACKAGE_XML [--rosdistro DIR]
Prints one line per key; exit status 0 when every key resolves.
"""
import argparse
import os
import sys

# Our keys as rosdistro resolved them for noetic / focal (ros/rosdistro 8468e88, 2026-08-22):
# ("ros", repository in noetic/distribution.yaml) or ("focal", Ubuntu packages from rosdep/*.yaml).
KNOWN = {
    "catkin": ("ros", "catkin"),
    "eigen": ("focal", ["libeigen3-dev"]),
    "roscpp": ("ros", "ros_comm"),
    "nodelet": ("ros", "nodelet_core"),
    "pluginlib": ("ros", "pluginlib"),
    "rosbag": ("ros", "ros_comm"),
    "sensor_msgs": ("ros", "common_msgs"),
    "nav_msgs": ("ros", "common_msgs"),
    "geometry_msgs": ("ros", "common_msgs"),
    "tf2": ("ros", "geometry2"),
    "tf2_msgs": ("ros", "geometry2"),
    "tf2_ros": ("ros", "geometry2"),
    "laser_geometry": ("ros", "laser_geometry"),
    "pcl_ros": ("ros", "perception_pcl"),
    "pcl_conversions": ("ros", "perception_pcl"),
    "diagnostic_updater": ("ros", "diagnostics"),
    "dynamic_reconfigure": ("ros", "dynamic_reconfigure"),
    "mrpt_libposes": ("ros", "mrpt_ros"),
    "mrpt_libros_bridge": ("ros", "mrpt_ros"),
    "rviz": ("ros", "rviz"),
    "gtest": ("focal", ["libgtest-dev"]),
    "rostest": ("ros", "ros_comm"),
    "roslaunch": ("ros", "ros_comm"),
    "qtbase5-dev": ("focal", ["qtbase5-dev"]),
    "xvfb": ("focal", ["xvfb"]),
}
# Keys that exist but must not be used on Noetic.
END_OF_LIFE = {"mrpt2": "end-of-life in noetic/distribution.yaml: mrpt_libposes, mrpt_libros_bridge, ..."}

CONDITIONS = {"ROS_VERSION": "1", "ROS_DISTRO": "noetic", "ROS_PYTHON_VERSION": "3"}
UBUNTU = "focal"


def package_keys(path):
    """{key: [dependency types]} of package.xml, conditions evaluated for Noetic."""
    from catkin_pkg.package import parse_package

    package = parse_package(path)
    package.evaluate_conditions(CONDITIONS)
    keys = {}
    for kind in ("buildtool_depends", "build_depends", "build_export_depends", "buildtool_export_depends",
                 "exec_depends", "test_depends", "doc_depends"):
        for dep in getattr(package, kind):
            if dep.evaluated_condition is False:
                continue
            keys.setdefault(dep.name, []).append(kind)
    return keys


def ubuntu_packages(rule):
    """The apt packages of one rosdep rule's `ubuntu:` entry for focal; None when there are none."""
    if rule is None:
        return None
    if isinstance(rule, str):
        return [rule]
    if isinstance(rule, list):
        return rule or None
    if isinstance(rule, dict):
        for key in (UBUNTU, "*", "apt", "packages"):
            if key in rule:
                return ubuntu_packages(rule[key])
        return None  # only other releases, or only another installer (pip, source)
    return None


def load_snapshot(root):
    import yaml

    rules = {}
    for name in ("base.yaml", "python.yaml"):
        with open(os.path.join(root, "rosdep", name)) as f:
            rules.update(yaml.safe_load(f))
    with open(os.path.join(root, "noetic", "distribution.yaml")) as f:
        distribution = yaml.safe_load(f)
    released = {}  # package -> (repository, status)
    for repo, entry in distribution["repositories"].items():
        release = entry.get("release")
        if not release:
            continue
        for package in release.get("packages", [repo]):
            released[package] = (repo, entry.get("status", ""))
    return rules, released


def resolve(key, rules, released):
    """(kind, value, problem): kind "ros" or "focal", problem None when the key is usable on Noetic."""
    if key in released:
        repo, status = released[key]
        return "ros", repo, ("%s is %s in noetic/distribution.yaml" % (key, status)
                             if status == "end-of-life" else None)
    if key in rules:
        packages = ubuntu_packages((rules[key] or {}).get("ubuntu"))
        if packages:
            return "focal", packages, None
        return None, None, "rosdep has %s, but no apt package for ubuntu %s" % (key, UBUNTU)
    return None, None, "%s is neither a Noetic package nor a rosdep key" % key


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("package_xml")
    parser.add_argument("--rosdistro", default=os.environ.get("LIDAR_DESKEW_ROSDISTRO") or None,
                        help="snapshot of ros/rosdistro (rosdep/, noetic/); default $LIDAR_DESKEW_ROSDISTRO, else ../shared/data/rosdistro beside the repo")
    args = parser.parse_args()
    if not args.rosdistro:
        # shared/data/rosdistro beside the repo (the project's shared data), when it has a snapshot
        beside = os.path.join(os.path.dirname(os.path.realpath(args.package_xml)), "..", "shared", "data",
                              "rosdistro")
        if os.path.isfile(os.path.join(beside, "noetic", "distribution.yaml")):
            args.rosdistro = os.path.normpath(beside)

    keys = package_keys(args.package_xml)
    snapshot = load_snapshot(args.rosdistro) if args.rosdistro else None
    failures = 0
    for key in sorted(keys):
        kinds = ",".join(k.replace("_depends", "") for k in keys[key])
        if snapshot:
            kind, value, problem = resolve(key, *snapshot)
            if not problem and KNOWN.get(key) != (kind, value):
                problem = "KNOWN says %s, the snapshot %s" % (KNOWN.get(key), (kind, value))
        elif key in END_OF_LIFE:
            problem, kind, value = END_OF_LIFE[key], None, None
        elif key in KNOWN:
            (kind, value), problem = KNOWN[key], None
        else:
            kind, value, problem = None, None, "%s is not in KNOWN: check it against a rosdistro snapshot" % key
        if problem:
            failures += 1
            print("FAIL %-20s (%s): %s" % (key, kinds, problem))
        else:
            where = ("Noetic package of " + value) if kind == "ros" else ("focal: " + " ".join(value))
            print("ok   %-20s (%s): %s" % (key, kinds, where))
    source = ("the rosdistro snapshot " + args.rosdistro) if snapshot else "KNOWN (no rosdistro snapshot given)"
    print("%d keys of %s against %s: %d passed, %d failed"
          % (len(keys), args.package_xml, source, len(keys) - failures, failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
