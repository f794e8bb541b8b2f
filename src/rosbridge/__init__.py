"""A rosbridge v2 websocket server: protocol core, ROS<->JSON conversion, rosapi, ROS side and Tornado shell."""
