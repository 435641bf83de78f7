"""A table as a :class:`rig.orchestrator.recorder.RunRecorder` sees it: the subscriptions of a real feedback hub,
fed by the test (tests/rig/test_recorder.py, test_recorder_limits.py)."""

from __future__ import annotations

from drivers.controller import AccelBatch, Feedback, Subscription


class FeedbackTable:
    """What a :class:`RunRecorder` reads from a table: the subscriptions of a real feedback hub."""

    def __init__(self) -> None:
        self.feedback = Feedback()

    def accelerations(self) -> Subscription[AccelBatch]:
        return self.feedback.subscribe("accel")

    def tilts(self) -> Subscription[object]:
        return self.feedback.subscribe("tilt")

    def statuses(self) -> Subscription[object]:
        return self.feedback.subscribe("status")

    def detections(self) -> Subscription[object]:
        return self.feedback.subscribe("detection")

    def faults(self) -> Subscription[object]:
        return self.feedback.subscribe("fault")

    def limit_trips(self) -> Subscription[object]:
        return self.feedback.subscribe("limit_trip")

    def controller_texts(self) -> Subscription[object]:
        return self.feedback.subscribe("controller_text")
