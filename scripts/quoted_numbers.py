#!/usr/bin/python3 -s
"""Measured figures quoted in README.md and docs/*.md, checked against the tools that print them.

A quoted figure is wrapped in invisible markers: <!--n:KEY-->VALUE<!--/n--> inline, or, for a whole
generated table, <!--n:KEY--> on the line before it and <!--/n--> on the line after. KEY names the run
that prints VALUE (FIGURES below); text after the key, up to the marker's end, is a note for readers.
This script runs those tools (only the runs the quoted keys need), then:

  --check   exits 1 naming each stale figure (file:line, key, quoted and printed), and any unknown key;
  --update  rewrites every marked figure with what the tools print;
  --list    prints every key it knows with its value.

  /usr/bin/python3 -s scripts/quoted_numbers.py --check|--update|--list [--bin DIR] [--jobs N] [FILE...]

FILE defaults to README.md and docs/*.md; --bin to the workspace's .build/ws/devel/lib/lidar_deskew.
The runs: deskew_calibrate and deskew_bag --consistency on data/neato_xv11/test_drive.bag (the demo's
real recording), and deskew_simulate + deskew_metrics on the paper's scenarios (tf at 50 Hz, noise off
and on; the rows of docs/RESULTS.md's main tables). About a minute on 2 cores. No timing figure is
quoted: speeds depend on the machine (bench/, docs/BENCHMARKS.md).
"""
import argparse
import concurrent.futures
import glob
import math
import os
import re
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NEATO_BAG = os.path.join(REPO, "data", "neato_xv11", "test_drive.bag")
TF_RATE = "50"
MARKER = re.compile(r"<!--n:([^\s>]+?)(?:\s[^>]*)?-->(.*?)<!--/n-->", re.S)
PAPER_HEADER = (
    "| scenario | scans | σ mm | raw RMS / p95 / max | corrected RMS / p95 / max "
    "| corrected scan RMS / p95 / max | laser_geometry RMS / p95 / max |\n"
    "| --- | ---: | ---: | --- | --- | --- | --- |")


class ToolError(Exception):
    pass


def run(command, allowed=(0,)):
    """Runs a tool; returns its stdout and stderr together; raises when its exit status is not allowed."""
    done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode not in allowed:
        raise ToolError("%s exited %d:\n%s" % (" ".join(command), done.returncode, done.stdout[-2000:]))
    return done.stdout


def find(pattern, text, what):
    found = re.search(pattern, text, re.M)
    if not found:
        raise ToolError("no %s in the output:\n%s" % (what, text[-2000:]))
    return found


class Runs:
    """The tools' runs, each done once, on demand."""

    def __init__(self, bin_dir, work, jobs):
        self.bin = bin_dir
        self.work = work
        self.jobs = jobs
        self.cache = {}

    def tool(self, name):
        return os.path.join(self.bin, name)

    def scenarios(self):
        if "scenarios" not in self.cache:
            self.cache["scenarios"] = run([self.tool("deskew_simulate"), "--list-paper"]).split()
        return self.cache["scenarios"]

    def paper_row(self, scenario, noise):
        """deskew_metrics --markdown's row for one paper scenario, noise off or on, tf at 50 Hz."""
        key = ("paper", scenario, noise)
        if key not in self.cache:
            slug = "%s-%s" % (scenario.replace("/", "_"), noise)
            bag, truth = (os.path.join(self.work, slug + ext) for ext in (".bag", ".truth"))
            run([self.tool("deskew_simulate"), "--scenario", scenario, "--bag", bag, "--truth", truth,
                 "--tf-rate", TF_RATE] + (["--noise"] if noise == "on" else []))
            lines = [l for l in run([self.tool("deskew_metrics"), bag, truth, "--markdown"]).splitlines()
                     if l.startswith("| ")]
            if len(lines) != 1:
                raise ToolError("deskew_metrics %s: expected one row, got %r" % (scenario, lines))
            os.remove(bag)
            os.remove(truth)
            self.cache[key] = lines[0]
        return self.cache[key]

    def paper_rows(self, noise):
        with concurrent.futures.ThreadPoolExecutor(self.jobs) as pool:
            return list(pool.map(lambda s: self.paper_row(s, noise), self.scenarios()))

    def demo(self):
        """The demo's simulated high-speed recording (ILD26TRI/high/arc, noise on), deskew_metrics' summary."""
        if "demo" not in self.cache:
            bag, truth = (os.path.join(self.work, "demo" + ext) for ext in (".bag", ".truth"))
            run([self.tool("deskew_simulate"), "--scenario", "ILD26TRI/high/arc", "--noise", "--bag", bag,
                 "--truth", truth])
            self.cache["demo"] = run([self.tool("deskew_metrics"), bag, truth])
        return self.cache["demo"]

    def calibrate(self, topic):
        """deskew_calibrate on the Neato bag: its output and the parameter file it wrote."""
        key = ("calibrate", topic)
        if key not in self.cache:
            params = os.path.join(self.work, "timing%s.yaml" % topic.replace("/", "_"))
            output = run([self.tool("deskew_calibrate"), NEATO_BAG, "--scan-topic", topic, "--output", params])
            self.cache[key] = (output, params)
        return self.cache[key]

    def neato_bag(self):
        """deskew_bag --consistency on the Neato bag's /stable_scan with deskew_calibrate's timing (the demo)."""
        if "neato_bag" not in self.cache:
            _, params = self.calibrate("/stable_scan")
            output_bag = os.path.join(self.work, "neato.bag")
            self.cache["neato_bag"] = run([self.tool("deskew_bag"), NEATO_BAG, output_bag, "--scan-topic", "/stable_scan",
                                           "--params", params, "--consistency"])
        return self.cache["neato_bag"]


# --- the figures -------------------------------------------------------------------------------------

def cells(row):
    return [c.strip() for c in row.strip().strip("|").split("|")]


PAPER_COLUMNS = {"raw": 3, "corrected": 4, "scan": 5, "laser_geometry": 6}


def paper_figure(runs, noise, scenario, field):
    row = runs.paper_row(scenario, noise)
    if field == "row":  # raw | corrected | laser_geometry, RMS / p95 / max each (the README's table)
        c = cells(row)
        return " | ".join(c[PAPER_COLUMNS[n]] for n in ("raw", "corrected", "laser_geometry"))
    name, _, statistic = field.rpartition("_")
    value = cells(row)[PAPER_COLUMNS[name]].split(" / ")[("rms", "p95", "max").index(statistic)]
    return value


def offset_of(output):
    found = find(r"first beam - stamp: (-?[0-9.]+) ms \+- ([0-9.]+) ms", output, "first beam - stamp")
    return float(found.group(1)), float(found.group(2))


def neato_figure(runs, field):
    calibrated, _ = runs.calibrate("/stable_scan")
    if field == "offset":  # the first beam before the stamp, ms +- 1 sigma
        offset, sigma = offset_of(calibrated)
        return "%.0f ± %.0f" % (-offset, sigma)
    if field in ("calibrate_raw", "calibrate_message"):  # deskew_calibrate's consistency over its pairs
        label = {"calibrate_raw": r"raw \(every beam at the stamp\)",
                 "calibrate_message": "corrected, the message's timing"}[field]
        return "%.1f" % float(find(r"^\s*%s: ([0-9.]+) mm" % label, calibrated, label).group(1))
    if field == "scan_late":  # /scan's offset minus /stable_scan's, negated: how late /scan is
        offset, sigma = offset_of(calibrated)
        late_offset, late_sigma = offset_of(runs.calibrate("/scan")[0])
        return "%.0f ± %.0f" % (offset - late_offset, math.hypot(sigma, late_sigma))
    summary = runs.neato_bag()
    if field in ("received", "published"):
        return find(r"/stable_scan: received (\d+), published (\d+)", summary, "summary").group(
            1 if field == "received" else 2)
    if field == "dropped":
        return find(r"dropped: tf (\d+)", summary, "dropped: tf").group(1)
    line = {"": "every pair", "turn": "pairs with a scan turning"}
    group, _, what = field.rpartition("_") if field.startswith("turn_") else ("", "", field)
    found = find(r"%s.*?: raw ([0-9.]+) mm \(spread [0-9.]+, (\d+) pairs\), corrected ([0-9.]+) mm" % line[group],
                 summary, line[group])
    return {"raw": found.group(1), "pairs": found.group(2), "corrected": found.group(3)}[what]


def demo_figure(runs, field):
    output = runs.demo()
    if field == "floor":
        return "%.0f" % float(find(r"range noise alone gives ([0-9.]+) mm", output, "noise floor").group(1))
    label = {"raw": "raw", "corrected": "corrected", "laser_geometry": "laser_geometry"}[field]
    return "%.0f" % float(find(r"^\s*%s\s+([0-9.]+) /" % label, output, label).group(1))


def figure(runs, key):
    """The value of one key, as the tools print it now; KeyError for an unknown key."""
    parts = key.split(".")
    try:
        if parts[0] == "paper" and parts[1] == "scenarios":  # how many scenarios: all, or the paper's own
            names = runs.scenarios()
            return str(len(names) if len(parts) == 2 else sum(not n.startswith("LDS-01/") for n in names))
        # docs/RESULTS.md's main tables, noise off or on
        if parts[0] == "paper" and len(parts) == 3 and parts[1] in ("off", "on") and parts[2] == "table":
            return "\n\n" + PAPER_HEADER + "\n" + "\n".join(runs.paper_rows(parts[1])) + "\n\n"
        if parts[0] == "paper" and len(parts) in (3, 4) and parts[1] in ("off", "on"):
            if parts[2] not in runs.scenarios():
                raise KeyError(key)
            return paper_figure(runs, parts[1], parts[2], parts[3] if len(parts) == 4 else "row")
        if parts[0] == "neato" and len(parts) == 2:
            return neato_figure(runs, parts[1])
        if parts[0] == "demo" and len(parts) == 2:
            return demo_figure(runs, parts[1])
    except (ValueError, IndexError):
        pass
    raise KeyError(key)


# --- the pages ---------------------------------------------------------------------------------------

def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true")
    mode.add_argument("--update", action="store_true")
    mode.add_argument("--list", action="store_true")
    parser.add_argument("--bin", default=os.path.join(REPO, ".build", "ws", "devel", "lib", "lidar_deskew"))
    parser.add_argument("--jobs", type=int, default=int(os.environ.get("LIDAR_DESKEW_JOBS", "2")))
    parser.add_argument("files", nargs="*")
    args = parser.parse_args()
    files = args.files or [os.path.join(REPO, "README.md")] + sorted(glob.glob(os.path.join(REPO, "docs", "*.md")))

    with tempfile.TemporaryDirectory(prefix="quoted_numbers.") as work:
        runs = Runs(args.bin, work, max(1, args.jobs))
        try:
            if args.list:
                keys = ["paper.scenarios", "paper.scenarios.paper", "paper.off.table", "paper.on.table"]
                keys += ["paper.off.%s" % s for s in runs.scenarios()]
                keys += ["neato." + f for f in ("offset", "calibrate_raw", "calibrate_message", "scan_late",
                                                "received", "published", "dropped", "raw", "corrected", "pairs",
                                                "turn_raw", "turn_corrected", "turn_pairs")]
                keys += ["demo." + f for f in ("raw", "corrected", "laser_geometry", "floor")]
                for key in keys:
                    print("%s: %s" % (key, figure(runs, key).strip().replace("\n", "\n    ")))
                print("and paper.off|on.SCENARIO (its row), "
                      "paper.off|on.SCENARIO.raw|corrected|scan|laser_geometry_rms|p95|max")
                return 0
            return check_or_update(files, runs, args.update)
        except ToolError as error:
            print("quoted_numbers: %s" % error, file=sys.stderr)
            return 2


def check_or_update(files, runs, update):
    # Every key first, so that the runs a table needs go in parallel.
    texts = {}
    for path in files:
        with open(path, encoding="utf-8") as page:
            texts[path] = page.read()
    keys = sorted({m.group(1) for text in texts.values() for m in MARKER.finditer(text)},
                  key=lambda k: not k.endswith(".table"))
    values, problems = {}, []
    for key in keys:
        try:
            values[key] = figure(runs, key)
        except KeyError:
            pass  # named below, with its place
    checked = 0
    for path, text in texts.items():
        name = os.path.relpath(path, REPO)
        for found in MARKER.finditer(text):
            key, quoted = found.group(1), found.group(2)
            if key not in values or "--" in key:  # "--" would end the HTML comment early on GitHub
                problems.append("%s:%d: unknown key %s" % (name, text.count("\n", 0, found.start()) + 1, key))
                continue
            checked += 1
            if quoted != values[key] and not update:
                line = text.count("\n", 0, found.start()) + 1
                if "\n" in quoted + values[key]:
                    stale = [l for l in quoted.splitlines() if l not in values[key].splitlines()]
                    fresh = [l for l in values[key].splitlines() if l not in quoted.splitlines()]
                    problems.append("%s:%d: %s: quoted\n    %s\n  printed\n    %s" % (
                        name, line, key, "\n    ".join(stale), "\n    ".join(fresh)))
                else:
                    problems.append("%s:%d: %s: quoted %s, printed %s" % (name, line, key, quoted, values[key]))
        if update:
            new = MARKER.sub(lambda m: m.group(0)[:m.start(2) - m.start(0)] + values.get(m.group(1), m.group(2))
                             + "<!--/n-->", text)
            if new != text:
                with open(path, "w", encoding="utf-8") as page:
                    page.write(new)
                print("updated %s" % name)
    for problem in problems:
        print(problem, file=sys.stderr)
    if not update:
        print("%d quoted figures in %d files, %d stale or unknown" % (checked, len(files), len(problems)))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
