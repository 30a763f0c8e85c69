"""An asyncio event loop in a daemon thread of its own, for aiortc.

aiortc needs an event loop, and the dashboard has none (Flask-SocketIO runs in threading mode) while the
robot's control loop must never wait on a peer connection. So the loop gets its own thread: web requests
hand it coroutines (`submit`) and wait for the result with a deadline on their own thread; the control loop
never calls into it. The encoders aiortc runs in the loop's executor are bounded to `ENCODER_THREADS`, so
video cannot take every core of the robot.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Coroutine
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")

#: Threads that encode video (aiortc encodes each frame in the loop's default executor).
ENCODER_THREADS = 2
#: Seconds `stop` waits for the loop's thread to end.
STOP_TIMEOUT_S = 5.0


class EventLoopThread:
    """An asyncio loop running in a daemon thread from `start` until `stop` (idempotent, restartable)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start the loop's thread unless it runs already; returns once the loop runs."""
        with self._lock:
            if self.running:
                return
            loop = asyncio.new_event_loop()
            loop.set_default_executor(ThreadPoolExecutor(ENCODER_THREADS, thread_name_prefix=f"{self.name}-encode"))
            started = threading.Event()
            loop.call_soon(started.set)
            thread = threading.Thread(target=self._run, args=(loop,), name=self.name, daemon=True)
            self._loop, self._thread = loop, thread
            thread.start()
        started.wait()

    @staticmethod
    def _run(loop: asyncio.AbstractEventLoop) -> None:
        asyncio.set_event_loop(loop)
        try:
            loop.run_forever()
        finally:
            pending = asyncio.all_tasks(loop)
            for task in pending:
                task.cancel()
            loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_default_executor())
            loop.close()

    def submit(self, coroutine: Coroutine[Any, Any, T]) -> Future[T]:
        """Run ``coroutine`` on the loop (started if need be); wait on the future with a timeout."""
        self.start()
        assert self._loop is not None
        return asyncio.run_coroutine_threadsafe(coroutine, self._loop)

    def stop(self) -> None:
        """Cancel what still runs, stop the loop and join its thread."""
        with self._lock:
            loop, thread = self._loop, self._thread
            self._loop = self._thread = None
        if loop is None or thread is None:
            return
        try:
            loop.call_soon_threadsafe(loop.stop)
        except RuntimeError:  # the loop is closed already (its thread ended)
            return
        thread.join(timeout=STOP_TIMEOUT_S)
