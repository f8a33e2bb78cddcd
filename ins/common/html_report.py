"""One self-contained HTML report: sections, tables, embedded PNG figures, escaped text.

The file needs nothing beside it and no network: the CSS is inline, every figure is a
``data:image/png;base64`` URI, there is no script, and a Content-Security-Policy
(``default-src 'none'; img-src data:; style-src 'unsafe-inline'``) makes the browser
refuse any other load, so a reference that slipped in would show as an error, not as a
silent fetch.  Every text given to a :class:`HtmlReport` method is escaped
(:func:`escape`); markup comes only from this module.

:meth:`HtmlReport.markdown` renders the Markdown subset of the toolkit's Markdown reports
(``#`` headings, ``-`` lists, ``|`` tables with an alignment row, paragraphs, ``**bold**``,
``` `code` ```, ``![title](name)`` figures taken from a given mapping), so that a
Markdown report and its HTML form have one source.

Shared by ``ins process --report`` (:mod:`ins.estimation.pipeline.report`) and
``photogrammetry refine --report F.html``.
"""
import base64
import html
import numbers
import os
import re

__all__ = ["HtmlReport", "escape", "png_data_uri", "PNG_MAGIC", "CSP"]

#: The first bytes of every PNG file.
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: The page's Content-Security-Policy: nothing loads but the inline style and data: images.
CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"

_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;
 color:#1d2330;background:#f4f5f7;margin:0}
main{max-width:1100px;margin:0 auto;padding:1.2em 1.6em 3em;background:#fff;
 box-shadow:0 0 6px rgba(0,0,0,.08)}
h1{font-size:1.6em;margin:.2em 0 .1em}
h2{font-size:1.25em;margin:1.6em 0 .5em;padding-bottom:.2em;border-bottom:1px solid #d6d9de}
h3{font-size:1.05em;margin:1.2em 0 .4em}
p.sub{color:#5a6270;margin:0 0 1em}
table{border-collapse:collapse;margin:.3em 0 1em;font-size:13px}
p.tcap{color:#5a6270;margin:.8em 0 0}
th,td{border:1px solid #d6d9de;padding:.25em .6em;vertical-align:top}
th{background:#eef0f3;text-align:left}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
tr:nth-child(even) td{background:#fafbfc}
code,pre{font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace;font-size:12.5px}
pre{background:#f6f7f9;border:1px solid #e1e4e8;padding:.6em;overflow-x:auto}
figure{margin:1em 0 1.6em}
figure img{max-width:100%;height:auto;border:1px solid #e1e4e8}
figcaption{color:#5a6270;font-size:13px;margin-top:.3em}
.verdict{border-left:6px solid;padding:.6em 1em;margin:.6em 0 1em;border-radius:3px}
.verdict h3{margin:.1em 0 .3em}
.verdict.ok{border-color:#2e7d32;background:#edf7ee}
.verdict.warn{border-color:#c77700;background:#fff6e5}
.verdict.poor{border-color:#c62828;background:#fdecea}
.timeline{display:flex;height:22px;border:1px solid #c3c7cd;margin:.4em 0 .2em}
.timeline div{height:100%}
.legend span{display:inline-block;margin-right:1.2em;font-size:12.5px}
.legend i{display:inline-block;width:12px;height:12px;margin-right:.3em;vertical-align:-1px;
 border:1px solid #999}
.axis{display:flex;justify-content:space-between;color:#5a6270;font-size:12px}
nav.toc{font-size:13px;margin:.5em 0 1em}
nav.toc a{margin-right:1em;color:#1a5fb4}
"""

_COLOUR = re.compile(r"#[0-9a-fA-F]{3,8}")
_IMAGE_LINE = re.compile(r"!\[(.*)\]\((.+)\)$")


def escape(text):
    """``text`` (any object, as ``str``) with ``& < > " '`` escaped for HTML."""
    return html.escape(str(text), quote=True)


def png_data_uri(png):
    """A ``data:image/png;base64,...`` URI of PNG bytes, or of the PNG file at a path.

    Raises
    ------
    ValueError
        The bytes are not a PNG.
    """
    if isinstance(png, (str, os.PathLike)):
        with open(png, "rb") as f:
            png = f.read()
    png = bytes(png)
    if not png.startswith(PNG_MAGIC):
        raise ValueError("not a PNG image (the file does not start with the PNG signature)")
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _inline(text):
    """Escaped ``text`` with Markdown ``**bold**`` and ``` `code` ``` turned into markup."""
    out = escape(text)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    return re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", out)


def _slug(text):
    return re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-") or "section"


class HtmlReport:
    """A report built section by section, then rendered (:meth:`html`) or written
    atomically (:meth:`write`).

    Parameters
    ----------
    title : str or None
        None: the first ``#`` heading of :meth:`markdown`.
    subtitle : str, optional
        A line under the title (what, when, where from).
    """

    def __init__(self, title, subtitle=None):
        self.title = "" if title is None else str(title)
        self.subtitle = subtitle
        self._parts = []
        self._sections = []
        self.images = 0                 # figures embedded so far

    def _add(self, markup):
        self._parts.append(markup)

    def heading(self, text, level=2):
        """A heading; level 2 headings are listed in the table of contents."""
        level = min(max(int(level), 2), 4)
        anchor = ""
        if level == 2:
            slug = _slug(text)
            while slug in (s for s, _ in self._sections):
                slug += "-x"
            self._sections.append((slug, str(text)))
            anchor = f' id="{slug}"'
        self._add(f"<h{level}{anchor}>{escape(text)}</h{level}>")

    def paragraph(self, text):
        self._add(f"<p>{escape(text)}</p>")

    def items(self, lines):
        """A bulleted list (nothing for an empty ``lines``)."""
        lines = list(lines)
        if lines:
            self._add("<ul>" + "".join(f"<li>{escape(x)}</li>" for x in lines) + "</ul>")

    def preformatted(self, lines):
        """Lines kept as they are (a summary printed by a command), monospaced."""
        self._add("<pre>" + escape("\n".join(lines)) + "</pre>")

    def table(self, header, rows, caption=None, numeric=None):
        """A table; ``numeric``: indices of right-aligned columns (default: every
        column whose cells are all numbers or empty, but the first)."""
        rows = [list(r) for r in rows]
        if numeric is None:
            numeric = {j for j in range(1, len(header))
                       if rows and all(_is_number(r[j]) for r in rows if j < len(r))}
        parts = [f'<p class="tcap">{escape(caption)}</p>' if caption else "", "<table>"]
        parts.append("<thead><tr>" + "".join(f"<th>{escape(h)}</th>" for h in header)
                     + "</tr></thead><tbody>")
        for r in rows:
            parts.append("<tr>" + "".join(
                f'<td class="num">{escape(_cell(c))}</td>' if j in numeric
                else f"<td>{escape(_cell(c))}</td>" for j, c in enumerate(r)) + "</tr>")
        parts.append("</tbody></table>")
        self._add("".join(parts))

    def verdict(self, level, title, reasons=()):
        """A coloured box: ``level`` ``"ok"`` (green), ``"warn"`` (amber) or ``"poor"``
        (red), a title and its reasons."""
        if level not in ("ok", "warn", "poor"):
            raise ValueError(f"verdict level must be ok, warn or poor, got {level!r}")
        body = "".join(f"<li>{escape(r)}</li>" for r in reasons)
        self._add(f'<div class="verdict {level}"><h3>{escape(title)}</h3>'
                  + (f"<ul>{body}</ul>" if body else "") + "</div>")

    def image(self, png, caption, alt=None):
        """A figure: PNG bytes or a PNG file, embedded as a data URI, with a caption."""
        uri = png_data_uri(png)
        self.images += 1
        self._add(f'<figure><img src="{uri}" alt="{escape(alt or caption)}">'
                  f"<figcaption>{escape(caption)}</figcaption></figure>")

    def timeline(self, segments, legend, start_label="", end_label=""):
        """A horizontal bar of coloured stretches (CSS only, no image).

        ``segments``: ``(fraction of the width, colour "#rrggbb", hover text)`` in
        order; ``legend``: ``(colour, label)``."""
        for _, colour, _ in segments:
            _check_colour(colour)
        for colour, _ in legend:
            _check_colour(colour)
        bar = "".join(f'<div style="width:{100 * max(float(w), 0):.4f}%;background:{c}" '
                      f'title="{escape(t)}"></div>' for w, c, t in segments)
        keys = "".join(f'<span><i style="background:{c}"></i>{escape(t)}</span>'
                       for c, t in legend)
        self._add(f'<div class="timeline">{bar}</div><div class="axis"><span>'
                  f"{escape(start_label)}</span><span>{escape(end_label)}</span></div>"
                  f'<div class="legend">{keys}</div>')

    def markdown(self, text, images=None):
        """Append Markdown ``text`` (the subset of the module notes); ``images`` maps
        each ``![title](name)`` name to PNG bytes or a file (a name not in it is an
        error: the file must not reference anything)."""
        images = images or {}
        lines = text.splitlines()
        i = 0
        para = []

        def flush():
            if para:
                self._add("<p>" + _inline(" ".join(para)) + "</p>")
                para.clear()
        while i < len(lines):
            line = lines[i].rstrip()
            if not line.strip():
                flush()
            elif line.startswith("#"):
                flush()
                level = len(line) - len(line.lstrip("#"))
                text_ = line[level:].strip()
                if level == 1:
                    self.title = self.title or text_
                else:
                    self.heading(text_.replace("**", ""), level)
            elif line.startswith("|"):
                flush()
                block = []
                while i < len(lines) and lines[i].startswith("|"):
                    block.append(lines[i].rstrip())
                    i += 1
                self._md_table(block)
                continue
            elif line.startswith("- "):
                flush()
                items = []
                while i < len(lines) and lines[i].startswith("- "):
                    items.append(lines[i][2:].strip())
                    i += 1
                self._add("<ul>" + "".join(f"<li>{_inline(x)}</li>" for x in items) + "</ul>")
                continue
            elif _IMAGE_LINE.match(line.strip()):
                flush()
                title, name = _IMAGE_LINE.match(line.strip()).groups()
                if name not in images:
                    raise ValueError(f"Markdown figure {name!r} has no image to embed")
                self.image(images[name], title)
            else:
                para.append(line.strip())
            i += 1
        flush()

    def _md_table(self, block):
        def cells(row):
            return [c.strip() for c in row.strip().strip("|").split("|")]
        header = cells(block[0])
        body = block[1:]
        right = set()
        if body and set(body[0].replace("|", "").strip()) <= set("-: "):
            right = {j for j, c in enumerate(cells(body[0])) if c.endswith(":")}
            body = body[1:]
        parts = ["<table><thead><tr>" + "".join(f"<th>{_inline(h)}</th>" for h in header)
                 + "</tr></thead><tbody>"]
        for row in body:
            parts.append("<tr>" + "".join(
                f'<td class="num">{_inline(c)}</td>' if j in right else f"<td>{_inline(c)}</td>"
                for j, c in enumerate(cells(row))) + "</tr>")
        self._add("".join(parts) + "</tbody></table>")

    def html(self):
        """The whole page as text."""
        toc = ""
        if len(self._sections) > 2:
            toc = ('<nav class="toc">' + "".join(
                f'<a href="#{s}">{escape(t)}</a>' for s, t in self._sections) + "</nav>")
        sub = f'<p class="sub">{escape(self.subtitle)}</p>' if self.subtitle else ""
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f'<meta http-equiv="Content-Security-Policy" content="{CSP}">'
                '<meta name="viewport" content="width=device-width, initial-scale=1">'
                f"<title>{escape(self.title)}</title><style>{_CSS}</style></head>\n"
                f"<body><main><h1>{escape(self.title)}</h1>{sub}{toc}\n"
                + "\n".join(self._parts) + "\n</main></body></html>\n")

    def write(self, path):
        """Write the page to ``path`` atomically (UTF-8); returns ``path``."""
        from ins.common.fileio import atomic_open
        with atomic_open(path, "wb") as f:
            f.write(self.html().encode("utf-8"))
        return path


def _check_colour(colour):
    if not _COLOUR.fullmatch(str(colour)):
        raise ValueError(f"colour must be #rgb or #rrggbb, got {colour!r}")


def _is_number(value):
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return True
    if isinstance(value, str):
        try:
            float(value.replace(",", "").replace("%", "").split()[0] if value.strip()
                  else "0")
            return True
        except (ValueError, IndexError):
            return False
    return value is None or hasattr(value, "dtype")


def _cell(value):
    """A table cell's text: ``str`` as it is, ``None`` empty, numbers with 4
    significant digits (integers whole)."""
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    try:
        return f"{float(value):.4g}"
    except (TypeError, ValueError):
        return str(value)
