// A whole bag's tf in one TfFeed, for tools that look at every scan of a recording afterwards
// (evaluation against truth, the consistency measure).
#pragma once

#include <rosbag/bag.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/ros/tf_feed.h"

namespace lidar_deskew::eval {

/// Feeds every /tf and /tf_static message of `bag`, in record order, into a TfFeed whose cache spans
/// the whole bag, so it answers for every scan; the live node's rules apply (docs/DESIGN.md §3): the
/// stamps of the LaserScans on `scan_topics` (and before the first, the record time) are the time line
/// tf must serve, which tells tf from a publisher on another clock from a time jump. Notes (statics
/// left out, time jumps, tf off the time line) go to `notes`, and the events' counts by kind to
/// `counts`, when given. Throws std::runtime_error naming the frames when tf never connects fixed_frame
/// to base_frame.
std::unique_ptr<ros_adapter::TfFeed> loadRecordedTf(
    rosbag::Bag& bag, const std::string& bag_path, const std::string& fixed_frame,
    const std::string& base_frame, std::string* notes = nullptr,
    const std::vector<std::string>& scan_topics = {},
    std::map<ros_adapter::TfEvent, std::size_t>* counts = nullptr);

/// Leaves out of `scans` those whose stamp tf cannot take: 0 (unset), or far from tf's time line
/// (TfFeed::coverage says never: an uninitialised stamp, another clock), as the node and deskew_bag
/// drop them. Returns how many it left out.
std::size_t dropStampsTfCannotTake(std::vector<core::PlanarScan>& scans, const ros_adapter::TfFeed& tf);

}  // namespace lidar_deskew::eval
