#include "lidar_deskew/bag/bag_deskew.h"

#include <rosbag/view.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>

#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::bag {
namespace {

using ros_adapter::PipelineEvent;

const char* const kTfTopic = "/tf";
const char* const kTfStaticTopic = "/tf_static";

std::string canonical(const std::string& path) {
  std::error_code error;
  const std::filesystem::path result = std::filesystem::weakly_canonical(path, error);
  return error ? path : result.string();
}

std::string joined(const std::vector<std::string>& items) {
  std::string text;
  for (const std::string& item : items)
    text += (text.empty() ? "" : ", ") + item;
  return text.empty() ? "none" : text;
}

}  // namespace

std::vector<std::string> laserScanTopics(rosbag::Bag& bag) {
  std::set<std::string> topics;
  for (const rosbag::ConnectionInfo* connection : rosbag::View(bag).getConnections()) {
    if (connection->datatype == "sensor_msgs/LaserScan")
      topics.insert(connection->topic);
  }
  return {topics.begin(), topics.end()};
}

BagDeskewSummary deskewBag(const BagDeskewOptions& options) {
  if (canonical(options.input) == canonical(options.output)) {
    throw std::runtime_error("refusing to write the output over the input (" + options.input + ")");
  }
  rosbag::CompressionType compression = rosbag::compression::Uncompressed;
  if (options.compression == "bz2") {
    compression = rosbag::compression::BZ2;
  } else if (options.compression == "lz4") {
    compression = rosbag::compression::LZ4;
  } else if (options.compression != "none") {
    throw std::runtime_error("compression must be none, bz2 or lz4, got '" + options.compression + "'");
  }
  options.params.validate();
  const auto inform = [&](const std::string& note) {
    if (options.inform)
      options.inform(note);
  };

  rosbag::Bag input = ros_adapter::openBagForReading(options.input);
  BagDeskewSummary summary;
  std::vector<std::string> available;
  try {
    available = laserScanTopics(input);
  } catch (const rosbag::BagException& error) {
    throw std::runtime_error("cannot read " + options.input + ": " + error.what());
  }
  summary.chosen_topics = options.scan_topics;
  if (summary.chosen_topics.empty()) {
    if (available.empty())
      throw std::runtime_error(options.input + " has no sensor_msgs/LaserScan topic");
    summary.chosen_topics = available;
    inform("no --scan-topic given: correcting " + joined(available) + " (the bag's LaserScan topics)");
  }
  std::map<std::string, std::unique_ptr<ros_adapter::ScanPipeline>> streams;  // by scan topic
  for (const std::string& topic : summary.chosen_topics) {
    if (std::find(available.begin(), available.end(), topic) == available.end()) {
      throw std::runtime_error(options.input + " has no LaserScan on " + topic +
                               "; its LaserScan topics: " + joined(available));
    }
    // Each kind of note once per topic; the counts are in the summary.
    auto said = std::make_shared<std::set<PipelineEvent>>();
    const auto report = [inform, topic, said](PipelineEvent event, const std::string& text) {
      // Statics left out are said once per frame by the pipeline already; mount changes, once here.
      if (event == PipelineEvent::kStaticIgnored || said->insert(event).second)
        inform(topic + ": " + text);
    };
    streams[topic] = std::make_unique<ros_adapter::ScanPipeline>(options.params, nullptr, report);
  }

  const auto corrected = [&streams] {
    std::size_t scans = 0;
    for (const auto& [name, pipeline] : streams)
      scans += pipeline->counters().published;
    return scans;
  };

  const std::string temporary = options.output + ".tmp-" + std::to_string(::getpid());
  try {
    rosbag::Bag output(temporary, rosbag::bagmode::Write);
    output.setCompression(compression);
    for (auto& [topic_name, pipeline] : streams) {
      const std::string topic = topic_name;  // captured by value: the lambda outlives this loop
      // Outputs are written at their scan's record time (the id it was given), next to it in the bag.
      pipeline->setPublish([&output, &options, topic](const ros_adapter::PipelineResult& result) {
        ros::Time record_time;
        record_time.fromNSec(result.id);
        output.write(options.replace ? topic : topic + "_deskewed", record_time, *result.outputs.scan);
        output.write(topic + "_deskewed_points", record_time, *result.outputs.cloud);
      });
    }

    rosbag::View view(input);
    const double begin = view.getBeginTime().toSec();
    const double span = std::max(1e-9, view.getEndTime().toSec() - begin);
    auto last_progress = std::chrono::steady_clock::now();
    for (const rosbag::MessageInstance& message : view) {
      if (options.interrupted && options.interrupted->load())
        throw Interrupted();
      const std::string& topic = message.getTopic();
      const double now = message.getTime().toSec();
      const auto stream = streams.find(topic);
      ++summary.messages;
      if (stream == streams.end()) {
        // Every other message as it was, its connection header (latching, callerid) included.
        output.write(topic, message.getTime(), message, message.getConnectionHeader());
        if (topic == kTfTopic || topic == kTfStaticTopic) {
          if (const auto transforms = message.instantiate<tf2_msgs::TFMessage>()) {
            for (auto& [name, pipeline] : streams)
              pipeline->addTransforms(transforms->transforms, topic == kTfStaticTopic, now);
          }
        }
      } else {
        const auto scan = message.instantiate<sensor_msgs::LaserScan>();
        if (!scan) {
          throw std::runtime_error(topic + " carries " + message.getDataType() +
                                   ", not sensor_msgs/LaserScan");
        }
        // The scan as read (read once), with its original connection header.
        output.write(options.replace ? topic + "_raw" : topic, message.getTime(), scan,
                     message.getConnectionHeader());
        stream->second->add(scan, now, message.getTime().toNSec());
      }
      for (auto& [name, pipeline] : streams)
        pipeline->expire(now);  // waiting measured in record time, as live on the wall clock

      const auto wall = std::chrono::steady_clock::now();
      if (options.progress && wall - last_progress > std::chrono::milliseconds(200)) {
        options.progress((now - begin) / span, corrected());
        last_progress = wall;
      }
    }
    for (auto& [topic, pipeline] : streams) {
      pipeline->flush();  // nothing more will come: what still waits has no tf
      summary.counters[topic] = pipeline->counters();
      const ros_adapter::PipelineCounters& counters = summary.counters[topic];
      if (counters.received > 0 && counters.published == 0) {
        const ros_adapter::TfFeed& tf = pipeline->tf();
        std::string error;
        if (!tf.buffer().canTransform(tf.fixedFrame(), tf.baseFrame(), ros::Time(0), &error)) {
          throw std::runtime_error(options.input + " has no tf from '" + tf.fixedFrame() + "' to '" +
                                   tf.baseFrame() + "' (set fixed_frame / base_frame); frames in its tf:\n" +
                                   tf.buffer().allFramesAsString());
        }
      }
    }
    output.close();
    if (std::rename(temporary.c_str(), options.output.c_str()) != 0) {
      throw std::runtime_error("cannot rename " + temporary + " to " + options.output);
    }
  } catch (const rosbag::BagException& error) {
    std::remove(temporary.c_str());
    throw std::runtime_error("failed reading " + options.input + " or writing " + options.output + ": " +
                             error.what());
  } catch (...) {
    std::remove(temporary.c_str());
    throw;
  }
  if (options.progress)
    options.progress(1.0, corrected());
  return summary;
}

}  // namespace lidar_deskew::bag
