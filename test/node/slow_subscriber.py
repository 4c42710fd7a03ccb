#!/usr/bin/python3 -s
"""A subscriber that is slow: it sleeps ~delay seconds in every callback of the deskew's outputs.

rospy runs callbacks on the thread that reads the connection, so while it sleeps nothing is read and
the publisher's socket fills up: the worst kind of slow subscriber. Messages are
taken as raw bytes (rospy.AnyMsg): only the reading is slow. Publishes how many messages it
has taken on ~received (std_msgs/UInt32) so a test can see that it is connected and really slow.
"""
import threading

import rospy
from std_msgs.msg import UInt32


def main():
    rospy.init_node("slow_subscriber")
    delay = rospy.get_param("~delay", 0.5)
    received = rospy.Publisher("~received", UInt32, queue_size=10, latch=True)
    lock = threading.Lock()
    count = [0]

    def callback(_message):
        with lock:
            count[0] += 1
            received.publish(UInt32(count[0]))
        rospy.sleep(delay)

    rospy.Subscriber("scan_deskewed", rospy.AnyMsg, callback, queue_size=1)
    rospy.Subscriber("scan_deskewed_points", rospy.AnyMsg, callback, queue_size=1)
    rospy.spin()


if __name__ == "__main__":
    main()
