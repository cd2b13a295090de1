"""What tests/ros2/watch.py (live, from the bus) and tests/ros2/bag.py (from a run's rosbag2)
decode of the fleet's ROS 2 messages, in one shape, so that tests/ros2.rs compares the two and
the telemetry: each message by its type and its topic's chunks after the namespace
(`vehicle_1`, `odom`), numbers as their shortest round-trip text, to the bit."""

import math


class Decoded:
    def __init__(self):
        self.odometry, self.clock, self.vectors, self.twists, self.paths, self.strings = {}, [], {}, {}, {}, {}

    def add(self, chunks, name, message):
        """`message` of type `name` on the topic whose chunks after the namespace are `chunks`."""
        if name.endswith("String"):
            # links/from_1_to_2/cause
            self.strings.setdefault("/".join(chunks), []).append(message.data)
        elif name.endswith("Twist"):
            self.twists.setdefault(chunks[0], []).append([repr(message.linear.x), repr(message.angular.z)])
        elif name.endswith("Clock"):
            self.clock.append([message.clock.sec, message.clock.nanosec])
        elif name.endswith("Path"):
            self.paths[chunks[0]] = {"frame": message.header.frame_id, "poses": [
                [p.header.stamp.sec, p.header.stamp.nanosec, p.pose.position.x, p.pose.position.y,
                 2.0 * math.atan2(p.pose.orientation.z, p.pose.orientation.w)] for p in message.poses]}
        elif name.endswith("Vector3Stamped"):
            # vehicle_1/gamma, links/from_1_to_2, coordination
            v = message.vector
            self.vectors.setdefault("/".join(chunks), []).append({
                "stamp": [message.header.stamp.sec, message.header.stamp.nanosec],
                "frame": message.header.frame_id, "x": repr(v.x), "y": repr(v.y), "z": repr(v.z)})
        else:
            pose, twist = message.pose.pose, message.twist.twist
            q = pose.orientation
            self.odometry.setdefault(chunks[0], []).append({
                "stamp": [message.header.stamp.sec, message.header.stamp.nanosec],
                "frame": message.header.frame_id, "child": message.child_frame_id,
                "x": repr(pose.position.x), "y": repr(pose.position.y),
                "yaw": repr(2.0 * math.atan2(q.z, q.w)), "yaw_rate": repr(twist.angular.z),
                "tilt": [q.x, q.y, pose.position.z], "velocity": [twist.linear.x, twist.linear.y]})

    def json(self):
        return {"clock": self.clock, "odometry": self.odometry, "vectors": self.vectors,
                "twists": self.twists, "paths": self.paths, "strings": self.strings}
