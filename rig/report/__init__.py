"""``rig report``: one self-contained HTML report of a session file or a study file (docs/architecture.md §4).

    from rig.report import write_report
    result = write_report("campaign.h5", "campaign.html")   # kind by the file's schema attribute

The page has no external reference (inline CSS, figures as base64 PNG, no script) and is laid out for A4
(`rig.report.html`). Figures: `rig.report.figures`; the response spectrum is `analysis.spectrum`; what is read:
`rig.report.data`; the sections: `rig.report.session_report` and `rig.report.study_report`.

The report is written atomically (a temporary file beside it, then renamed) and never over an input file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from .data import ReportError, file_kind
from .html import page
from .session_report import Progress, session_body
from .study_report import study_body


@dataclass(frozen=True)
class ReportResult:
    """What `write_report` wrote: the input's kind (``"session"`` | ``"study"``), the output path, its size
    [bytes], the number of figures and the time it took [s]."""

    kind: str
    output: Path
    bytes: int
    figures: int
    seconds: float

    def as_dict(self) -> dict[str, object]:
        """JSON-ready."""
        return {"kind": self.kind, "output": str(self.output), "bytes": self.bytes, "figures": self.figures,
                "seconds": round(self.seconds, 3)}


def build_report(path: str | os.PathLike[str], progress: Progress | None = None) -> tuple[str, str, int]:
    """(kind, the HTML document, number of figures) for a session or study file."""
    kind = file_kind(path)
    if kind == "session":
        title, body, n = session_body(str(path), progress)
    else:
        title, body, n = study_body(str(path))
    generated = datetime.now(UTC).isoformat(timespec="seconds")
    footer = f'<p class="note">Generated {generated} by shaketable-rig from {Path(path).name}.</p>'
    return kind, page(title, body + footer, generated), n


def _same_file(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    try:
        return b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def write_report(source: str | os.PathLike[str], output: str | os.PathLike[str],
                 progress: Progress | None = None) -> ReportResult:
    """Write the report of ``source`` to ``output`` atomically (temporary file + rename; an existing report is
    replaced). `ReportError` if ``output`` is the input file or its directory does not exist."""
    t0 = time.perf_counter()
    source, output = Path(source), Path(output)
    if _same_file(source, output):
        raise ReportError(f"{output}: is the input file; the report is never written over an input")
    if output.suffix.lower() in (".h5", ".hdf5"):
        raise ReportError(f"{output}: an HDF5 name for an HTML report; choose a name ending in .html")
    if not output.parent.is_dir():
        raise ReportError(f"{output}: directory {output.parent} does not exist")
    kind, document, n = build_report(source, progress)
    data = document.encode("utf-8")
    tmp = output.with_name(f".{output.name}.{secrets.token_hex(6)}.tmp")
    try:
        with open(tmp, "xb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, output)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    with contextlib.suppress(OSError):
        fd = os.open(output.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return ReportResult(kind, output, len(data), n, time.perf_counter() - t0)


__all__ = ["ReportError", "ReportResult", "build_report", "file_kind", "write_report"]
