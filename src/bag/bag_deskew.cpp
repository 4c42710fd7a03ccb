#include "lidar_deskew/bag/bag_deskew.h"

#include <pcl_ros/point_cloud.h>  // DeskewedCloud written to bags
#include <rosbag/view.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <tuple>

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

/// The outputs of a scan: the corrected scan and its cloud.
void writeOutputs(rosbag::Bag& output, const std::string& topic, bool replace, const ros::Time& time,
                  const ros_adapter::DeskewedOutputs& outputs) {
  output.write(replace ? topic : topic + "_deskewed", time, *outputs.scan);
  output.write(topic + "_deskewed_points", time, *outputs.cloud);
}

/// The outputs of a cloud: the corrected cloud, and its planar scan with cloud_scan.
void writeOutputs(rosbag::Bag& output, const std::string& topic, bool replace, const ros::Time& time,
                  const ros_adapter::CloudOutputs& outputs) {
  output.write(replace ? topic : topic + "_deskewed", time, *outputs.cloud);
  if (outputs.scan)
    output.write(topic + "_deskewed_scan", time, *outputs.scan);
}

/// One topic to correct and its pipeline.
class Stream {
 public:
  virtual ~Stream() = default;
  virtual void addTransforms(const std::vector<geometry_msgs::TransformStamped>& transforms, bool is_static,
                             double now) = 0;
  /// Writes the message as read (its connection header kept) and feeds it to the pipeline.
  virtual void add(const rosbag::MessageInstance& message, double now) = 0;
  virtual void expire(double now) = 0;
  virtual void flush() = 0;
  virtual const ros_adapter::PipelineCounters& counters() const = 0;
  virtual const ros_adapter::TfFeed& tf() const = 0;
};

template <class Processor>
class PipelineStream final : public Stream {
 public:
  using Pipeline = ros_adapter::SweepPipeline<Processor>;
  using Message = typename Processor::Message;

  /// `inform` receives the first note of each kind, and of a failure the first of each cause.
  PipelineStream(const std::string& topic, const BagDeskewOptions& options, rosbag::Bag& output,
                 std::function<void(const std::string&)> inform)
      : topic_(topic),
        replace_(options.replace),
        output_(output),
        inform_(std::move(inform)),
        // Outputs are written at their sweep's record time (the id it was given), next to it in the bag.
        // Scans wait for the recording's tf, however late it was recorded (ros_adapter::Waiting).
        pipeline_(
            options.params,
            [this](const typename Pipeline::Result& result) {
              ros::Time record_time;
              record_time.fromNSec(result.id);
              writeOutputs(output_, topic_, replace_, record_time, result.outputs);
            },
            [this](PipelineEvent event, const std::string& text) { note(event, text); }, 10.0,
            ros_adapter::Waiting::kRecording) {}

  void addTransforms(const std::vector<geometry_msgs::TransformStamped>& transforms, bool is_static,
                     double now) override {
    pipeline_.addTransforms(transforms, is_static, now);
  }
  void add(const rosbag::MessageInstance& message, double now) override {
    const auto sweep = message.instantiate<Message>();
    if (!sweep) {
      throw std::runtime_error(topic_ + " carries " + message.getDataType() + ", not " +
                               ros::message_traits::DataType<Message>::value());
    }
    // As read (read once), with its original connection header.
    output_.write(replace_ ? topic_ + "_raw" : topic_, message.getTime(), sweep,
                  message.getConnectionHeader());
    pipeline_.add(sweep, now, message.getTime().toNSec());
  }
  void expire(double now) override { pipeline_.expire(now); }
  void flush() override { pipeline_.flush(); }
  const ros_adapter::PipelineCounters& counters() const override { return pipeline_.counters(); }
  const ros_adapter::TfFeed& tf() const override { return pipeline_.tf(); }

 private:
  /// Each kind of note once (the counts are in the summary); statics left out are said once per frame
  /// by the pipeline already. A scan dropped or passed through is said for the first of each cause
  /// (the pipeline counts it under its cause before it reports it).
  void note(PipelineEvent event, const std::string& text) {
    const ros_adapter::PipelineCounters& counters = pipeline_.counters();
    const std::size_t causes = counters.dropped_by_cause.size() + counters.passed_by_cause.size();
    const bool new_cause = causes > causes_said_;
    causes_said_ = causes;
    const bool new_kind = said_.insert(event).second;
    if (event == PipelineEvent::kStaticIgnored || new_cause || new_kind)
      inform_(topic_ + ": " + text);
  }

  std::string topic_;
  bool replace_;
  rosbag::Bag& output_;
  std::function<void(const std::string&)> inform_;
  std::set<PipelineEvent> said_;
  std::size_t causes_said_ = 0;
  Pipeline pipeline_;
};

}  // namespace

std::vector<std::string> topicsOfType(rosbag::Bag& bag, const std::string& datatype) {
  std::set<std::string> topics;
  for (const rosbag::ConnectionInfo* connection : rosbag::View(bag).getConnections()) {
    if (connection->datatype == datatype)
      topics.insert(connection->topic);
  }
  return {topics.begin(), topics.end()};
}

std::vector<std::string> laserScanTopics(rosbag::Bag& bag) {
  return topicsOfType(bag, "sensor_msgs/LaserScan");
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
  std::vector<std::string> scans_available, clouds_available;
  try {
    scans_available = laserScanTopics(input);
    clouds_available = topicsOfType(input, "sensor_msgs/PointCloud2");
  } catch (const rosbag::BagException& error) {
    throw std::runtime_error("cannot read " + options.input + ": " + error.what());
  }
  std::vector<std::string> scan_topics = options.scan_topics;
  std::vector<std::string> cloud_topics = options.cloud_topics;
  if (scan_topics.empty() && cloud_topics.empty()) {
    if (!scans_available.empty()) {
      scan_topics = scans_available;
      inform("no --scan-topic given: correcting " + joined(scans_available) +
             " (the bag's LaserScan topics)");
    } else if (!clouds_available.empty()) {
      cloud_topics = clouds_available;
      inform("no --scan-topic or --cloud-topic given: correcting " + joined(clouds_available) +
             " (the bag's PointCloud2 topics)");
    } else {
      throw std::runtime_error(options.input +
                               " has no sensor_msgs/LaserScan or sensor_msgs/PointCloud2 topic");
    }
  }
  summary.cloud_topics = cloud_topics;
  for (const auto& [topics, available, type] :
       {std::make_tuple(&scan_topics, &scans_available, "LaserScan"),
        std::make_tuple(&cloud_topics, &clouds_available, "PointCloud2")}) {
    for (const std::string& topic : *topics) {
      if (std::find(available->begin(), available->end(), topic) == available->end()) {
        throw std::runtime_error(options.input + " has no " + type + " on " + topic + "; its " + type +
                                 " topics: " + joined(*available));
      }
      summary.chosen_topics.push_back(topic);
    }
  }
  std::map<std::string, std::unique_ptr<Stream>> streams;  // by topic

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
    for (const std::string& topic : scan_topics) {
      streams[topic] =
          std::make_unique<PipelineStream<ros_adapter::ScanProcessor>>(topic, options, output, inform);
    }
    for (const std::string& topic : cloud_topics) {
      streams[topic] =
          std::make_unique<PipelineStream<ros_adapter::CloudProcessor>>(topic, options, output, inform);
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
        stream->second->add(message, now);
      }
      for (auto& [name, pipeline] : streams)
        pipeline->expire(now);  // tf that stopped coming: record time bounds the wait (and the memory)

      const auto wall = std::chrono::steady_clock::now();
      if (options.progress && wall - last_progress > std::chrono::milliseconds(200)) {
        options.progress((now - begin) / span, corrected());
        last_progress = wall;
      }
    }
    for (auto& [topic, pipeline] : streams) {
      pipeline->flush();  // nothing more will come: each scan still waiting is decided alone
      summary.counters[topic] = pipeline->counters();
      const ros_adapter::PipelineCounters& counters = summary.counters[topic];
      if (counters.received > 0 && counters.published == 0) {
        const ros_adapter::TfFeed& tf = pipeline->tf();
        if (const std::string why = tf.whyNoChain(); !why.empty())
          throw std::runtime_error(options.input + ": " + why + " (set fixed_frame / base_frame)");
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
