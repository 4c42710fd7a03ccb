// A test-only rviz panel: publishes the status of every enabled display, and rviz's global status,
// as a diagnostic_msgs/DiagnosticArray on ~display_status (twice a second), so that a test can fail
// when a display warns or errs. rviz 1.14 offers no other way to read display statuses from outside.
//
// Not part of the package's exports: test/CMakeLists.txt builds it into a tiny package of its own in
// the build folder, which rviz_neato.sh puts on ROS_PACKAGE_PATH, and adds the panel to a copy of the
// config under test (add_status_probe.py). The panel hides its own dock widget.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <rviz/display.h>
#include <rviz/display_group.h>
#include <rviz/panel.h>
#include <rviz/properties/status_list.h>
#include <rviz/visualization_manager.h>
#include <pluginlib/class_list_macros.hpp>

#include <QTimer>

namespace lidar_deskew_test {
namespace {
// A display's status list ("Status", created with its first status), or null.
rviz::StatusList* statusListOf(const rviz::Property& property) {
  for (int i = 0; i < property.numChildren(); ++i) {
    if (auto* list = dynamic_cast<rviz::StatusList*>(property.childAt(i))) {
      return list;
    }
  }
  return nullptr;
}

// One diagnostic status per status list: level = the list's (rviz's Ok/Warn/Error are 0/1/2, as
// diagnostic_msgs' OK/WARN/ERROR), one key per entry ("Topic", "Transform", ...) with "Level: text".
diagnostic_msgs::DiagnosticStatus toDiagnostic(const std::string& name, const std::string& class_id,
                                               const rviz::StatusList& list) {
  diagnostic_msgs::DiagnosticStatus status;
  status.name = name;
  status.hardware_id = class_id;
  status.level = static_cast<uint8_t>(list.getLevel());
  for (int i = 0; i < list.numChildren(); ++i) {
    const auto* entry = dynamic_cast<const rviz::StatusProperty*>(list.childAt(i));
    if (entry == nullptr) {
      continue;
    }
    diagnostic_msgs::KeyValue value;
    value.key = entry->getNameStd();
    value.value = (rviz::StatusProperty::statusWord(entry->getLevel()) + ": " + entry->getValue().toString())
                      .toStdString();
    if (entry->getLevel() == list.getLevel() && status.message.empty()) {
      status.message = value.key + ": " + value.value;
    }
    status.values.push_back(value);
  }
  return status;
}

// Every enabled display below `group`, depth first; names are paths ("group/display").
void collect(const rviz::DisplayGroup& group, const std::string& prefix,
             diagnostic_msgs::DiagnosticArray& out) {
  for (int i = 0; i < group.numDisplays(); ++i) {
    const rviz::Display* display = group.getDisplayAt(i);
    if (display == nullptr || !display->isEnabled()) {
      continue;
    }
    const std::string name = prefix + display->getNameStd();
    if (const rviz::StatusList* list = statusListOf(*display)) {
      out.status.push_back(toDiagnostic(name, display->getClassId().toStdString(), *list));
    }
    if (const auto* subgroup = dynamic_cast<const rviz::DisplayGroup*>(display)) {
      collect(*subgroup, name + "/", out);
    }
  }
}
}  // namespace

class DisplayStatusProbe : public rviz::Panel {
 public:
  void onInitialize() override {
    publisher_ = ros::NodeHandle("~").advertise<diagnostic_msgs::DiagnosticArray>("display_status", 10);
    auto* timer = new QTimer(this);
    connect(timer, &QTimer::timeout, this, [this] { publish(); });
    timer->start(500);
    // A probe, not a panel to look at: once the window is laid out, hide the dock it sits in.
    QTimer::singleShot(0, this, [this] {
      if (parentWidget() != nullptr) {
        parentWidget()->hide();
      }
    });
  }

 private:
  void publish() {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    const rviz::DisplayGroup* root = vis_manager_->getRootDisplayGroup();
    // rviz's own "Global Status" (fixed frame) is a status list among the root group's properties.
    for (int i = 0; i < root->numChildren(); ++i) {
      if (const auto* list = dynamic_cast<const rviz::StatusList*>(root->childAt(i))) {
        const QString label = list->getName();  // "Global Status: Ok"
        array.status.push_back(toDiagnostic(label.section(':', 0, 0).toStdString(), "rviz", *list));
      }
    }
    collect(*root, "", array);
    publisher_.publish(array);
  }

  ros::Publisher publisher_;
};

}  // namespace lidar_deskew_test

PLUGINLIB_EXPORT_CLASS(lidar_deskew_test::DisplayStatusProbe, rviz::Panel)
