"""The drive camera over WebRTC (issue 26): the robot sends its camera to the Control page with aiortc, for
lower latency than MJPEG, which stays the fallback.

`loop.EventLoopThread` runs aiortc's asyncio loop in a thread of its own; `track.CameraTrack` turns the
newest camera frame into video frames; `sender.DriveVideo` keeps one peer connection per page and answers
its offer; `events` signals over the dashboard's Socket.IO connection. aiortc is optional (the ``webrtc``
extra) and imported only when a page asks for WebRTC: without it the page says MJPEG and why.
"""
