#!/usr/bin/python3 -s
"""rostest node of rviz_neato.test: rviz shows the Neato bag through the live nodelet, without a
display warning or erring, and its screenshot shows every display's colour.

While the bag plays (on the ROS clock) it reads the statuses that the test-only DisplayStatusProbe
panel publishes (~status_topic). Once the bag has ended and ~settle seconds have passed, it saves a
screenshot of the X display ($DISPLAY, `import -window root`) and asserts:
- every enabled display of the config reports, with level Ok; a display with a topic has received
  messages; and no status was Warn or Error after the first ~warmup seconds of the bag (until then a
  display may rightly say it has no messages yet);
- inside the 3D view (the rows and columns mostly of its background colour), at least ~min_pixels pixels of each
  flat colour of the config, and as many of a colour map (saturated colours that are none of the flat
  ones) for each display coloured by a channel.
The statuses and counts are written beside the screenshot (SCREENSHOT.txt).
"""
import subprocess
import sys
import threading
import time
import unittest

import numpy
import rosbag
import rospy
import rostest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock

LEVELS = {0: "Ok", 1: "Warn", 2: "Error"}
TOLERANCE = 12  # per channel, for flat colours (rviz draws points unshaded)


def enabled_displays(displays):
    """(path, display config) of every enabled display, groups flattened."""
    for display in displays:
        if not display.get("Enabled", True):
            continue
        yield display["Name"], display
        if display.get("Class") == "rviz/Group":
            for name, child in enabled_displays(display.get("Displays", [])):
                yield display["Name"] + "/" + name, child


def parse_color(text):
    return tuple(int(part) for part in str(text).split(";"))


def read_screenshot(path):
    """The screenshot as an H x W x 3 uint8 array (through ImageMagick's binary PPM)."""
    ppm = subprocess.run(["convert", path, "-depth", "8", "ppm:-"], check=True, capture_output=True).stdout
    fields = ppm.split(maxsplit=4)
    assert fields[0] == b"P6" and fields[3] == b"255", fields[:4]
    width, height = int(fields[1]), int(fields[2])
    return numpy.frombuffer(fields[4][: width * height * 3], numpy.uint8).reshape(height, width, 3)


def view_area(image, background):
    """The 3D view: the rows and columns mostly of the background colour (points and grid are sparse)."""
    is_background = numpy.all(image == background, axis=2)
    rows = numpy.nonzero(is_background.mean(axis=1) > 0.5)[0]
    cols = numpy.nonzero(is_background.mean(axis=0) > 0.5)[0]
    if rows.size == 0 or cols.size == 0:
        return image[:0, :0]
    return image[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]


def near(image, color):
    return numpy.all(numpy.abs(image.astype(int) - numpy.array(color)) <= TOLERANCE, axis=2)


class RvizNeato(unittest.TestCase):
    def setUp(self):
        rospy.init_node("check_rviz", anonymous=True)
        self.config_path = rospy.get_param("~config")
        self.screenshot = rospy.get_param("~screenshot")
        self.settle = rospy.get_param("~settle", 2.0)
        self.warmup = rospy.get_param("~warmup", 1.0)
        self.min_pixels = rospy.get_param("~min_pixels", 300)
        self.timeout = rospy.get_param("~timeout", 60.0)
        with rosbag.Bag(rospy.get_param("~bag")) as bag:
            self.bag_start, self.bag_end = bag.get_start_time(), bag.get_end_time()
        with open(self.config_path) as stream:
            self.config = yaml.safe_load(stream)
        self.lock = threading.Lock()
        self.statuses = []  # (bag time [s], DiagnosticArray)
        self.clock = None
        rospy.Subscriber("/clock", Clock, self.on_clock, queue_size=10)
        rospy.Subscriber(rospy.get_param("~status_topic", "/rviz/display_status"), DiagnosticArray,
                         self.on_status, queue_size=100)

    def on_clock(self, message):
        with self.lock:
            self.clock = message.clock.to_sec()

    def on_status(self, message):
        with self.lock:
            self.statuses.append((self.clock, message))

    def wait_for_bag_end(self):
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline and not rospy.is_shutdown():
            with self.lock:
                if self.clock is not None and self.clock >= self.bag_end - 0.05:
                    return
            time.sleep(0.1)
        self.fail("the bag did not play to its end (%.1f s) within %.0f s; clock: %s"
                  % (self.bag_end - self.bag_start, self.timeout, self.clock))

    def test_rviz_shows_the_bag(self):
        self.wait_for_bag_end()
        time.sleep(self.settle)
        subprocess.run(["import", "-window", "root", self.screenshot], check=True)
        with self.lock:
            statuses = list(self.statuses)
        report, failures = [], []

        # Statuses: the last report, then every report after the warm-up.
        self.assertTrue(statuses, "no display status from rviz: did the probe panel load?")
        last = {status.name: status for status in statuses[-1][1].status}
        report.append("statuses at the end (bag time %.1f s):" % (statuses[-1][0] - self.bag_start))
        for status in last.values():
            report.append("  %-50s %-5s %s" % (status.name, LEVELS.get(status.level, status.level),
                                               "; ".join("%s: %s" % (v.key, v.value) for v in status.values)))
        for name, display in enabled_displays(self.config["Visualization Manager"]["Displays"]):
            if name not in last:
                failures.append("display %r reported no status" % name)
                continue
            values = {v.key: v.value for v in last[name].values}
            if "Topic" in display and not values.get("Topic", "").endswith("messages received"):
                failures.append("display %r received no messages: %s" % (name, values.get("Topic")))
        seen = set()
        for clock, array in statuses:
            if clock is None or clock < self.bag_start + self.warmup:
                continue
            for status in array.status:
                for value in status.values:
                    if not value.value.startswith("Ok") and (status.name, value.key, value.value) not in seen:
                        seen.add((status.name, value.key, value.value))
                        failures.append("at bag time %.1f s display %r: %s: %s"
                                        % (clock - self.bag_start, status.name, value.key, value.value))

        # Pixels of every display's colour inside the 3D view.
        image = read_screenshot(self.screenshot)
        options = self.config["Visualization Manager"]["Global Options"]
        view = view_area(image, parse_color(options.get("Background Color", "48; 48; 48")))
        report.append("screenshot %s: %dx%d, 3D view %dx%d" % (self.screenshot, image.shape[1], image.shape[0],
                                                               view.shape[1], view.shape[0]))
        displays = [(name, display) for name, display in
                    enabled_displays(self.config["Visualization Manager"]["Displays"]) if "Topic" in display]
        flat = [parse_color(d.get("Color", "255; 255; 255")) for _, d in displays
                if d.get("Color Transformer") == "FlatColor"]
        for name, display in displays:
            if display.get("Color Transformer") == "FlatColor":
                what = "colour %s" % display.get("Color")
                pixels = int(near(view, parse_color(display.get("Color"))).sum())
            else:
                what = "colour map (%s %s)" % (display.get("Color Transformer"), display.get("Channel Name", ""))
                spread = view.max(axis=2).astype(int) - view.min(axis=2)
                colour_map = spread >= 100
                for color in flat:
                    colour_map &= ~near(view, color)
                pixels = int(colour_map.sum())
            report.append("  %-50s %6d pixels of %s" % (name, pixels, what))
            if pixels < self.min_pixels:
                failures.append("display %r: %d pixels of its %s in the 3D view, fewer than %d"
                                % (name, pixels, what, self.min_pixels))

        report += ["FAIL: " + failure for failure in failures] or ["PASS"]
        with open(self.screenshot + ".txt", "w") as stream:
            stream.write("\n".join(report) + "\n")
        print("\n".join(report), file=sys.stderr)
        self.assertFalse(failures, "\n".join(failures))


if __name__ == "__main__":
    rostest.rosrun("lidar_deskew", "rviz_neato", RvizNeato, sys.argv)
