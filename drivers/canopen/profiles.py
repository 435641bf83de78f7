"""Manufacturer profiles: which drives' objects in 0x2000–0x5FFF the master may use, by their identity (0x1018).

A manufacturer object means what its vendor says: 0x2010 is the target delay on the project's leg drive and
"active fieldbus" (one byte) on a maxon EPOS4. So the master reads or maps an object of that range only on a drive
whose vendor-ID and product code (0x1018 sub 1, sub 2) match a :class:`DriveProfile` that defines it. A new drive
with useful vendor objects gets a profile here (``docs/table-controller.md``, *Describing a new drive*).
"""

from __future__ import annotations

from dataclasses import dataclass

from protocols.canopen import od as drive_od


@dataclass(frozen=True)
class DriveProfile:
    """A drive model's manufacturer objects the master uses: ``target_delay`` and ``feedback_delay`` (UNSIGNED32
    [µs]: a target latched at a SYNC is reached this long after it; a reported position is this much older than its
    SYNC) and ``answered_sync`` (UNSIGNED8, PDO-mappable: the counter of the SYNC a TPDO answers, for counted
    SYNCs); None where the drive has none."""

    name: str
    vendor_id: int
    product_code: int
    target_delay: int | None = None
    feedback_delay: int | None = None
    answered_sync: int | None = None

    @property
    def features(self) -> tuple[str, ...]:
        """What the profile adds to a standard drive, in words."""
        return tuple(name for name, index in (("target delay", self.target_delay),
                                               ("feedback delay", self.feedback_delay),
                                               ("SYNC counter echo", self.answered_sync)) if index is not None)


PROFILES = (
    DriveProfile("shaketable-rig leg drive", drive_od.LEG_DRIVE_VENDOR_ID, drive_od.LEG_DRIVE_PRODUCT_CODE,
                 target_delay=drive_od.TARGET_DELAY, feedback_delay=drive_od.FEEDBACK_DELAY,
                 answered_sync=drive_od.ANSWERED_SYNC),
)
"""The drives with a known manufacturer profile (the emulated drives are the project's leg drive)."""


def profile_of(vendor_id: int, product_code: int) -> DriveProfile | None:
    """The profile of a drive with this identity; None for any other drive (standard objects only)."""
    return next((p for p in PROFILES if (p.vendor_id, p.product_code) == (vendor_id, product_code)), None)
