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

    def offer(self, text: str, droppable: bool = True) -> bool:
        """Queue ``text``; never waits. When the queue is full a ``droppable`` message (a live frame) is dropped and
        counted; any other (a status: the state must not go stale) takes the place of the oldest queued message,
        which is counted as dropped instead. Whether ``text`` was queued."""
        if self.queue.full():
            self.dropped += 1
            if droppable:
                return False
            self.queue.get_nowait()
        self.queue.put_nowait(text)
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

    def publish(self, text: str, droppable: bool = True) -> None:
        """Offer ``text`` to every browser (:meth:`Browser.offer`)."""
        self.published += 1
        for browser in list(self.browsers):
            browser.offer(text, droppable)

    def stats(self) -> dict[str, object]:
        """Messages published and, per browser, queued, sent and dropped."""
        return {"published": self.published,
                "browsers": [{"source": b.source, "queued": b.queued, "sent": b.sent, "dropped": b.dropped}
                             for b in self.browsers]}
