# The parameters that may change while a node runs (rqt_reconfigure, `dynparam set`), shared by
# DeskewScan.cfg (the LaserScan node) and DeskewCloud.cfg (the PointCloud2 node): each offers only the
# parameters its input reads. Names, defaults, bounds and the input each applies to are those of the
# parameter table (src/ros/deskew_params.cpp, docs/PARAMETERS.md); test_reconfigure checks both generated
# descriptions against it. A change applies to scans that arrive (stamp_at, time_offset, beam_order,
# scan_period, use_scan_period) or are corrected (the rest) after it.
from dynamic_reconfigure.parameter_generator_catkin import ParameterGenerator, bool_t, double_t, int_t, str_t

BOTH, SCANS, CLOUDS = "both", "scans", "clouds"


def generate(node, name):
    """Writes the config `name` with the parameters `node` (SCANS or CLOUDS) reads; returns the exit code."""
    gen = ParameterGenerator()

    def add(input_kind, *args, **kwargs):
        if input_kind in (BOTH, node):
            gen.add(*args, **kwargs)

    def choices(param, values, meaning):
        return gen.enum([gen.const(param + "_" + value, str_t, value, value) for value in values], meaning)

    add(BOTH, "reference", str_t, 0, "time every point is re-expressed at; outputs are stamped with it",
        "start", edit_method=choices("reference", ["start", "middle", "end"], "reference time"))
    add(SCANS, "stamp_at", str_t, 0, "which beam header.stamp refers to", "start",
        edit_method=choices("stamp_at", ["start", "end"], "the beam of header.stamp"))
    add(BOTH, "time_offset", double_t, 0, "[s] added to header.stamp (before stamp_at): a fixed latency",
        0.0, -10.0, 10.0)
    add(SCANS, "beam_order", str_t, 0, "the beams' order in time is their index order, or its reverse",
        "as_message", edit_method=choices("beam_order", ["as_message", "reversed"], "order of the beams in time"))
    add(SCANS, "scan_period", double_t, 0, "[s] revolution time when time_increment and scan_time are 0; 0 = none",
        0.0, 0.0, 60.0)
    add(SCANS, "use_scan_period", bool_t, 0, "beam spacing from scan_period even when the message gives one",
        False)
    add(BOTH, "tf_timeout", double_t, 0, "[s] longest wait for tf to cover a sweep's last beam", 0.2, 0.0, 60.0)
    add(BOTH, "on_tf_failure", str_t, 0, "what happens to a scan tf does not cover", "drop",
        edit_method=choices("on_tf_failure", ["drop", "pass_through"], "scans tf does not cover"))
    add(BOTH, "max_tf_gap", double_t, 0, "[s] refuse sweeps tf interpolates across a longer gap; 0 = never",
        0.5, 0.0, 60.0)
    add(BOTH, "max_extrapolation", double_t, 0,
        "[s] after tf_timeout without tf, extrapolate at most this far instead of failing; 0 = never",
        0.0, 0.0, 1.0)
    add(BOTH, "queue_size", int_t, 0, "[scans] scans waiting for tf at most", 10, 1, 100000)
    add(SCANS, "rebin_min_gap", double_t, 0, "[m] contour join distance, constant part", 0.05, 0.0, 100.0)
    add(SCANS, "rebin_gap_factor", double_t, 0, "contour join distance per (range x angle increment)",
        5.0, 0.0, 1000.0)
    add(BOTH, "diagnostics_period", double_t, 0, "[s] period of /diagnostics (more than 0)", 1.0, 0.001, 3600.0)
    # The planar scan of the corrected points (when cloud_scan is on).
    add(CLOUDS, "scan_height_min", double_t, 0, "[m] the band's lowest z in the cloud's frame", -0.1, -100.0, 100.0)
    add(CLOUDS, "scan_height_max", double_t, 0, "[m] the band's highest z", 0.1, -100.0, 100.0)
    add(CLOUDS, "scan_angle_min", double_t, 0, "[rad] the planar scan's first bearing", -3.14159, -3.15, 3.15)
    add(CLOUDS, "scan_angle_max", double_t, 0, "[rad] its last bearing", 3.14159, -3.15, 3.15)
    add(CLOUDS, "scan_angle_increment", double_t, 0, "[rad] its bin width", 0.00436332, 1e-5, 1.0)
    add(CLOUDS, "scan_range_max", double_t, 0, "[m] its range_max (more than 0)", 100.0, 0.001, 10000.0)
    return gen.generate("lidar_deskew", "lidar_deskew", name)
