"""The report's HTML: one self-contained page (inline CSS, figures as ``data:`` PNG, no script, no network).

Laid out for A4: the body is at most 180 mm wide (the text width of an A4 page with 15 mm margins), figures take
100 % of it, tables use a compact font so that the widest (Table III's twelve columns) fits; ``@page`` sets A4
for printing and sections with a figure are not split across pages.
"""

from __future__ import annotations

import base64
import html as _html
from collections.abc import Collection, Iterable, Sequence
from typing import Any

CSS = """
@page { size: A4; margin: 15mm; }
html { font: 10pt/1.35 "DejaVu Sans", "Liberation Sans", Arial, sans-serif; color: #111; background: #fff; }
body { max-width: 180mm; margin: 0 auto; padding: 0 3mm 10mm; }
h1 { font-size: 15pt; margin: 6mm 0 2mm; }
h2 { font-size: 12.5pt; margin: 7mm 0 2mm; border-bottom: 1px solid #999; }
h3 { font-size: 10.5pt; margin: 5mm 0 1.5mm; }
p { margin: 1.5mm 0; }
p.note, figcaption, .small { font-size: 8pt; color: #333; }
figure { margin: 2mm 0 3mm; break-inside: avoid; page-break-inside: avoid; }
figure img { display: block; width: 100%; height: auto; }
table { border-collapse: collapse; width: 100%; margin: 1.5mm 0 3mm; font-size: 7.5pt; }
caption { caption-side: top; text-align: left; font-size: 8pt; font-weight: bold; padding-bottom: 1mm; }
th, td { padding: 0.6mm 1.2mm; border-bottom: 1px solid #ddd; text-align: right; vertical-align: top;
         overflow-wrap: break-word; }
td.w, table.kv td { overflow-wrap: anywhere; }
th { border-bottom: 1px solid #777; font-weight: bold; background: #f3f3f3; }
th.l, td.l { text-align: left; }
table.kv th { text-align: left; width: 28%; background: none; border-bottom: 1px solid #ddd; }
table.kv td { text-align: left; }
tr.avg td { font-weight: bold; }
section.run { break-inside: avoid; page-break-inside: avoid; }
.warn { color: #a40; }
@media print { body { max-width: none; padding: 0; } h2 { break-after: avoid; } }
"""


def esc(value: Any) -> str:
    """Text for HTML (``None`` → "–")."""
    return "–" if value is None else _html.escape(str(value), quote=True)


def num(value: Any, fmt: str = ".3g", scale: float = 1.0) -> str:
    """A number formatted with ``fmt`` after multiplying by ``scale``; None/NaN → "–"; other values as text."""
    if value is None:
        return "–"
    try:
        x = float(value)
    except (TypeError, ValueError):
        return esc(value)
    if x != x:  # NaN
        return "–"
    return format(x * scale, fmt)


def table(headers: Sequence[str], rows: Iterable[Sequence[Any]], *, caption: str = "", left: int = 0,
          wrap: Collection[int] = (), row_classes: Sequence[str] | None = None, raw: bool = False) -> str:
    """A table: ``headers`` (already HTML-safe text), ``rows`` of cells (escaped unless ``raw``); the first
    ``left`` columns left-aligned; the columns in ``wrap`` (long names, paths) may break anywhere, the others
    only between words."""
    def cls(i: int, cell: bool = True) -> str:
        names = ["l"] * (i < left) + ["w"] * (cell and i in wrap)
        return f' class="{" ".join(names)}"' if names else ""

    out = ["<table>"]
    if caption:
        out.append(f"<caption>{caption}</caption>")
    out.append("<thead><tr>" + "".join(f"<th{cls(i, False)}>{h}</th>" for i, h in enumerate(headers)) + "</tr></thead>")
    out.append("<tbody>")
    for k, row in enumerate(rows):
        rc = f' class="{row_classes[k]}"' if row_classes and row_classes[k] else ""
        cells = "".join(f"<td{cls(i)}>{c if raw else esc(c)}</td>" for i, c in enumerate(row))
        out.append(f"<tr{rc}>{cells}</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def key_values(pairs: Iterable[tuple[str, Any]]) -> str:
    """A two-column table of names and values (values escaped)."""
    rows = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in pairs)
    return f'<table class="kv"><tbody>{rows}</tbody></table>'


def figure(png: bytes, caption: str, alt: str) -> str:
    """A figure: the PNG embedded as base64, with its caption (HTML-safe text)."""
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{esc(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{caption}</figcaption></figure>")


def page(title: str, body: str, generated: str) -> str:
    """The whole document."""
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f'<meta name="generator" content="shaketable-rig report, {esc(generated)}">\n'
        f"<title>{esc(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
        f"{body}\n</body>\n</html>\n"
    )
