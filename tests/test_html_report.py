"""The HTML writer (:mod:`ins.common.html_report`): text escaped everywhere, a complete
page (every element closed, parsed back by the standard library's parser), nothing
external referenced (every src a data: URI that decodes to the given PNG, no http(s)
src or href), the Markdown subset of the refine report; the GNSS quality runs of the
process report (:func:`ins.estimation.pipeline.report.quality_runs`) on hand-made logs."""
import base64
import re
import zlib
from html.parser import HTMLParser

import pytest

from ins.common.html_report import CSP, PNG_MAGIC, HtmlReport, escape, png_data_uri
from ins.estimation.pipeline.report import quality_runs

EVIL = '<script>alert("x")</script> & <img src=x onerror=alert(1)> \'q\''
VOID = {"meta", "img", "br", "hr", "link", "input"}


def _png(width=3, height=2):
    """A valid RGB PNG, written here byte by byte (not by the code under test)."""
    def chunk(kind, data):
        return (len(data).to_bytes(4, "big") + kind + data
                + zlib.crc32(kind + data).to_bytes(4, "big"))
    raw = b"".join(b"\0" + bytes([200, 30, 30]) * width for _ in range(height))
    ihdr = width.to_bytes(4, "big") + height.to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])
    return (PNG_MAGIC + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw))
            + chunk(b"IEND", b""))


class _Tree(HTMLParser):
    """Start/end tags balanced, attributes and text collected."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack, self.attrs, self.text, self.errors = [], [], [], []

    def handle_starttag(self, tag, attrs):
        self.attrs.append((tag, dict(attrs)))
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


def _parse(page):
    tree = _Tree()
    tree.feed(page)
    tree.close()
    return tree


def _full_report(png):
    r = HtmlReport("Title " + EVIL, "sub " + EVIL)
    r.heading("Section " + EVIL)
    r.heading("Second")
    r.heading("Third")
    r.paragraph("para " + EVIL)
    r.items(["item " + EVIL])
    r.preformatted(["pre " + EVIL, "line 2"])
    r.table(("h " + EVIL, "n"), [("cell " + EVIL, 1.5), ("b", 2)], caption="cap " + EVIL)
    r.verdict("poor", "verdict " + EVIL, ["reason " + EVIL])
    r.image(png, "figure " + EVIL)
    r.timeline([(0.5, "#2e7d32", "tip " + EVIL), (0.5, "#c62828", "b")],
               [("#2e7d32", "fix " + EVIL)], "0 s", "1 s")
    return r


def test_every_text_is_escaped_and_the_page_is_complete(tmp_path):
    png = _png()
    page = _full_report(png).write(tmp_path / "r.html")
    text = (tmp_path / "r.html").read_text(encoding="utf-8")
    assert page == tmp_path / "r.html"
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    # no markup of the user's text survives: the only script-like text is escaped
    assert "<script" not in text and "onerror=alert" not in text.replace(
        "&lt;img src=x onerror=alert(1)&gt;", "")
    assert text.count(escape(EVIL)) >= 10
    tree = _parse(text)
    assert not tree.errors and not tree.stack, (tree.errors, tree.stack)
    # the parsed text gives the user's strings back exactly
    joined = "".join(tree.text)
    for word in ("para ", "item ", "pre ", "cell ", "verdict ", "reason ", "fix "):
        assert word + EVIL in joined
    titles = [a.get("title") for t, a in tree.attrs if t == "div" and "title" in a]
    assert "tip " + EVIL in titles
    assert [a["alt"] for t, a in tree.attrs if t == "img"] == ["figure " + EVIL]


def test_nothing_external_is_referenced(tmp_path):
    png = _png(5, 4)
    text = _full_report(png).html()
    tree = _parse(text)
    refs = [(t, k, v) for t, a in tree.attrs for k, v in a.items() if k in ("src", "href")]
    assert refs, "the page has an image and a table of contents"
    for tag, key, value in refs:
        assert not re.match(r"\s*(https?:|//|file:)", value, re.I), (tag, key, value)
        assert value.startswith(("data:image/png;base64,", "#"))
    srcs = [v for t, k, v in refs if k == "src"]
    assert [base64.b64decode(v.split(",", 1)[1]) for v in srcs] == [png]
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*https?://""", text, re.I)
    assert "@import" not in text and "url(" not in text
    metas = [a for t, a in tree.attrs if t == "meta"]
    assert {"http-equiv": "Content-Security-Policy", "content": CSP} in metas
    assert "<script" not in text


def test_only_png_images_and_known_colours():
    with pytest.raises(ValueError, match="PNG"):
        png_data_uri(b"GIF89a....")
    r = HtmlReport("t")
    with pytest.raises(ValueError, match="colour"):
        r.timeline([(1.0, "red;background:url(http://x)", "t")], [])
    with pytest.raises(ValueError):
        r.verdict("maybe", "t")
    with pytest.raises(ValueError, match="no image"):
        r.markdown("![plot](elsewhere.png)")


def test_markdown_subset():
    png = _png()
    r = HtmlReport(None)
    r.markdown("# The title\n\n- method **known-base**, `phi-omega-kappa`\n- b < c\n\n"
               "## Part & more\n\nA paragraph\ncontinued.\n\n"
               "| | rx | ry |\n|---|---:|---:|\n| **sigma** | 1.0 | 2.0 |\n\n"
               "![residuals](res.png)\n", images={"res.png": png})
    text = r.html()
    assert "<title>The title</title>" in text
    assert "<li>method <strong>known-base</strong>, <code>phi-omega-kappa</code></li>" in text
    assert "<li>b &lt; c</li>" in text
    assert '<h2 id="part-more">Part &amp; more</h2>' in text
    assert "<p>A paragraph continued.</p>" in text
    assert "<td><strong>sigma</strong></td><td class=\"num\">1.0</td>" in text
    assert text.count("data:image/png;base64,") == 1 and r.images == 1
    tree = _parse(text)
    assert not tree.errors and not tree.stack


def test_quality_runs_of_hand_made_logs():
    # 1 Hz: 5 fixes, 3 floats, a 10 s gap, 2 fixes; the flags and times given out of order
    t = [0, 1, 2, 3, 4, 5, 6, 7, 17, 18]
    q = [1, 1, 1, 1, 1, 2, 2, 2, 1, 1]
    runs = quality_runs(t[::-1], q[::-1])
    assert runs == [(0.0, 4.0, 1, 5), (5.0, 7.0, 2, 3), (7.0, 17.0, None, 0),
                    (17.0, 18.0, 1, 2)]
    assert quality_runs([10.0, 11.0, 12.0]) == [(10.0, 12.0, 0, 3)]
    assert quality_runs([]) == []


@pytest.mark.parametrize("name, message", [
    ("report.md", "expected an .html file"),
    ("out/sub/report.html", "inside a subfolder of OUT_DIR"),
    ("missing/report.html", "does not exist"),
])
def test_process_report_option_refused_before_the_work(tmp_path, capsys, name, message):
    """A --report that could not be written stops at once (exit 2), naming it; nothing
    is written (the flight folder need not even exist: the option is checked first)."""
    from ins.cli.main import main
    out = tmp_path / "out"
    assert main(["process", str(tmp_path / "no_flight"), "-o", str(out), "--report",
                 str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert message in err and "report" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_process_report_sections_of_a_raw_gnss_run(tmp_path):
    """The sections a simulated flight does not reach, on a stand-in result: RTKLIB as
    the source (its 'poor' reason makes the verdict amber), the forward/backward
    separation (RMS and max computed here from the differences), a re-anchoring, the
    identified noise, and a PNG no section claims."""
    from types import SimpleNamespace

    import numpy as np

    from ins.estimation.pipeline.report import process_report
    from ins.gnss.separation import Separation
    from ins.io.gnss_log import GnssLog

    rng = np.random.default_rng(5)
    n = 50
    d = rng.normal(0.0, [0.004, 0.006, 0.01], (n, 3))
    qf = np.where(np.arange(n) < 40, 1, 2)
    sep = Separation(time=100.0 + np.arange(n), d_neu_m=d, q_forward=qf,
                     q_backward=np.ones(n, int))
    t = 100.0 + np.arange(n, dtype=float)
    log = GnssLog(time=t, lla=np.zeros((n, 3)), sigma_ned_m=np.full((n, 3), 0.02),
                  quality=qf)
    m = 5
    result = SimpleNamespace(
        counts={"imu_epochs": 5000, "nodes": m, "gnss_records": n, "updates": n,
                "rejected": 0, "outside_imu_span": 0, "mount_fallback": 0,
                "recoveries": 0, "reanchors": 1, "gnss_steps": 0},
        quality={"tested": n, "rejected": 0, "rejected_fraction": 0.0,
                 "residual_rms_m": 0.01, "residual_max_m": 0.03, "warnings": [],
                 "error": None, "sensor_ratio": {}},
        gnss_source={"path": "/x/gnss.pos", "mode": "kinematic", "direction": "combined",
                     "ephemeris": "broadcast", "counts": {1: 40, 2: 10},
                     "rover_epochs": n, "repaired": 0, "dropped": 0,
                     "poor": "few fixes <test>", "separation": sep},
        fwd=SimpleNamespace(recoveries=[], reanchors=[(120.0, 125.0, 6, 40.0)]),
        start_check=None, alignment=None, gnss=log, errors_smoothed=None,
        errors_forward=None, smoothed_sensors=np.zeros((m, 12)),
        smoothed_std=np.ones((m, 21)) * 1e-6,
        identified=SimpleNamespace(describe=lambda: "ARW 0.1 deg/sqrt(h) & <more>"))
    extra = tmp_path / "extra.png"
    extra.write_bytes(_png(7, 3))
    text = process_report(result, plots=[str(extra)]).html()
    tree = _parse(text)
    assert not tree.errors and not tree.stack
    body = "".join(tree.text)
    assert "Trusted, with warnings" in body and "RTKLIB's solution: few fixes <test>" in body
    assert "verdict warn" in text
    rms, mx = 1e3 * np.sqrt(np.mean(d ** 2, axis=0)), 1e3 * np.max(np.abs(d), axis=0)
    rms3 = 1e3 * np.max(np.linalg.norm(d, axis=1))
    row = [f"{v:.1f}" for v in (*rms, *mx, rms3)]
    assert f"<td>all epochs both solved</td><td class=\"num\">{n}</td>" in text
    assert "".join(f'<td class="num">{v}</td>' for v in row) in text
    assert "re-anchoring" in body and "120.00" in body and "x40" in body
    assert "ARW 0.1 deg/sqrt(h) & <more>" in body
    assert "Other figures" in body and text.count("data:image/png;base64,") == 1
    # the quality flags: 40 fix then 10 float, no gap
    assert "<td>fix</td><td class=\"num\">40</td>" in text
    assert "<td>float</td><td class=\"num\">10</td>" in text
