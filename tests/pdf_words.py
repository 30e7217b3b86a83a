"""Read a PDF back as words with their boxes (``pdftotext -bbox`` of poppler-utils) and find
the words that leave a page's frame: what the report tests use to see that no table or
label runs past a margin."""

from __future__ import annotations

import html as html_lib
import re
import shutil
import subprocess

import pytest

#: the page margins of the print stylesheet (pt; 1 mm = 72 / 25.4 pt): top, right, bottom, left
PRINT_MARGINS_PT = tuple(mm / 25.4 * 72 for mm in (20, 15, 18, 15))
#: WeasyPrint's default page margin (75 CSS px, in pt): the HTML page set on paper
DEFAULT_MARGIN_PT = 75 * 0.75


def require_poppler():
    """Skip unless pdftotext and pdftoppm are on the PATH."""
    if shutil.which("pdftoppm") is None or shutil.which("pdftotext") is None:
        pytest.skip("pdftoppm/pdftotext not found (Debian package poppler-utils; .ci/run installs it)")


def poppler(*argv) -> str:
    """The standard output of a poppler-utils command."""
    return subprocess.run(argv, capture_output=True, text=True, check=True, timeout=300).stdout


def words(pdf):
    """Per page: (page width, height, [(x0, y0, x1, y1, word)]) from ``pdftotext -bbox`` (pt)."""
    pages = []
    for page in re.findall(r'<page width="([\d.]+)" height="([\d.]+)">(.*?)</page>', poppler(
            "pdftotext", "-bbox", str(pdf), "-"), re.S):
        found = [(float(a), float(b), float(c), float(d), html_lib.unescape(w)) for a, b, c, d, w in re.findall(
            r'<word xMin="([-\d.]+)" yMin="([-\d.]+)" xMax="([-\d.]+)" yMax="([-\d.]+)">(.*?)</word>', page[2])]
        pages.append((float(page[0]), float(page[1]), found))
    return pages


def outside_frame(pages, margins, slack: float = 1.0):
    """``[(page, word, box)]`` of every word whose box leaves the page's frame: its left
    and right margins (``margins`` = top, right, bottom, left in pt), or the page itself
    above and below (the running header and footer live in the top and bottom margins)."""
    _top, right, _bottom, left = margins
    out = []
    for i, (width, height, found) in enumerate(pages, 1):
        for x0, y0, x1, y1, word in found:
            if x0 < left - slack or x1 > width - right + slack or y0 < -slack or y1 > height + slack:
                out.append((i, word, (round(x0, 1), round(y0, 1), round(x1, 1), round(y1, 1))))
    return out
