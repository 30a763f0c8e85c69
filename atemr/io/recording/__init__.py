"""Recording every run to MCAP, reading recordings back (up to any damage), and the topics both agree on.

`topics` names every channel with its schema (ROS 2 messages for sensors and geometry, JSON with a JSON
schema for the agent's own data); `codec` turns messages into the bytes of a channel; `mcap_writer` writes
them to rotated files without ever blocking the control loop; `mcap_reader` reads a file back, a truncated
one up to its last complete chunk; `agent_trace` reads the agent's records of a recording (or of an old
``.atrace`` file) for ``atemr trace show`` and the Agent page's replay.
"""
