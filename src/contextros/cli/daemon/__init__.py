"""The CLI's daemon: a long-lived helper that keeps a ROS participant warm for commands.

A `contextros activate|deactivate|switch|status` pays about 0.4 s of rclpy start-up and
discovery before it can ask the manager anything. The daemon pays it once: it holds client
nodes that have discovered the manager, and serves commands over a Unix socket that only
its user can reach (as `ros2 daemon` serves the ros2 CLI's graph queries). The first
command starts it in the background and asks the manager itself; the next ones go through
it. It stops after a while without commands, or with `contextros daemon stop`.

- `place`: where a daemon lives (one per ROS environment and installation) and who may
  reach it;
- `wire`: the local protocol (one JSON request, one JSON answer) and its checks;
- `client`: the command line's side (no rclpy);
- `server`: the daemon itself.
"""
