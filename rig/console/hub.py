"""The browsers connected to the console: one bounded queue each, frames dropped (and counted) when a browser falls
behind, so that a slow or closed browser never holds up the feed (nor, through it, the service or its logging)."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

QUEUE_FRAMES = 32
"""Messages waiting for one browser at most (1.6 s of live frames at 20 Hz); more are dropped."""


@dataclass(eq=False)
class Browser:
    """One connected browser: its queue of JSON texts, what was queued for it and what was dropped."""

    source: str
    capacity: int = QUEUE_FRAMES
    queued: int = 0
    dropped: int = 0
    sent: int = 0
    queue: asyncio.Queue[str] = field(init=False)

    def __post_init__(self) -> None:
        self.queue = asyncio.Queue(self.capacity)

    def offer(self, text: str) -> bool:
        """Queue ``text`` unless the queue is full (then it is dropped and counted); never waits."""
        try:
            self.queue.put_nowait(text)
        except asyncio.QueueFull:
            self.dropped += 1
            return False
        self.queued += 1
        return True


class Hub:
    """Every connected browser; :meth:`publish` offers a message to each (in the event loop's thread)."""

    def __init__(self, capacity: int = QUEUE_FRAMES) -> None:
        self.capacity = capacity
        self.browsers: set[Browser] = set()
        self.published = 0

    def connect(self, source: str) -> Browser:
        browser = Browser(source, self.capacity)
        self.browsers.add(browser)
        return browser

    def disconnect(self, browser: Browser) -> None:
        self.browsers.discard(browser)

    def publish(self, text: str) -> None:
        self.published += 1
        for browser in list(self.browsers):
            browser.offer(text)

    def stats(self) -> dict[str, object]:
        """Messages published and, per browser, queued, sent and dropped."""
        return {"published": self.published,
                "browsers": [{"source": b.source, "queued": b.queued, "sent": b.sent, "dropped": b.dropped}
                             for b in self.browsers]}
