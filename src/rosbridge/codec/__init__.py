"""The converters, named by direction, over one table of field types (fields.py):
- ros_to_json.py: a message's ROS bytes (as read from TCPROS) -> its JSON text, one reader generated per type;
- json_to_ros.py: a client's parsed JSON -> the message's ROS bytes, one packer generated per type;
- json_values.py: ROS message objects <-> JSON-ready values (the slow road, which the two above must equal;
  service calls, rosapi), and dumps, the one way the bridge writes JSON text;
- ros_to_cbor.py: a message's ROS bytes -> the values cbor2 writes (its numeric arrays as typed arrays of the bytes
  as they are), one reader generated per type;
- cbor.py: ROS message objects -> CBOR, and CBOR as parts; wrapping.py: JSON text <-> png ops and fragment ops.
All pure: no rospy, no tornado."""

# bytes: a byte string this long (an image's data) is cheaper to write to the socket by reference, as a part of
# its frame, than to copy into one frame with the rest (protocol/encoded.SplicedFrame)
BIG_BYTES = 1 << 16
