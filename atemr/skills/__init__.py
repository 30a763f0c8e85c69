"""The algorithms: pure functions and small stateful objects, no I/O, time from an injected clock."""
