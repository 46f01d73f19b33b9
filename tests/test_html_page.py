"""OUT/index.html: written by Results.write, self-contained, escaped, complete; sortable in a real browser."""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.reports.html import render_html

XSS_LABEL = "<script>x</script>"
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")

# a smallest GIF (1x1, one frame): stands in for the per-cell animation another module writes
TINY_GIF = base64.b64decode("R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw==")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[ev.Results, Path]:
    """Two consensus configurations (one labelled with markup), one map, two slips, short episodes."""
    spec = ev.RunSpec(
        envs=["KoopNav-TargetReaching-v0"],
        controllers=["consensus", f"consensus:goal_gain=2.0,label={XSS_LABEL}"],
        maps=["map1"],
        slips=["nominal", "high"],
        episodes=2,
        seed=3,
        env_kwargs={"max_episode_steps": 30},
    )
    results = ev.evaluate(spec, workers=1, progress=False)
    out = tmp_path_factory.mktemp("run")
    (out / "animations").mkdir()
    (out / "animations" / "consensus_map1_high.gif").write_bytes(TINY_GIF)
    for rec in results.records:
        if (rec["controller"], rec["slip"], rec["trial"]) == ("consensus", "high", 0):
            rec["animation"] = "animations/consensus_map1_high.gif"
        if (rec["controller"], rec["slip"], rec["trial"]) == (XSS_LABEL, "high", 0):
            rec["animation"] = "animations/missing.gif"
    results.config["command"] = "python evaluate.py --controllers consensus --episodes 2"
    paths = results.write(out)
    assert paths["html"] == out / "index.html"
    return results, out


@pytest.fixture(scope="module")
def page(run) -> str:
    return (run[1] / "index.html").read_text(encoding="utf-8")


class _Tables(HTMLParser):
    """Every <table>: header texts and row texts, as a browser would show them (entities decoded)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: list[tuple[list[str], list[list[str]]]] = []
        self._cell: list[str] | None = None
        self._row: list[str] = []
        self._in_head = False

    def handle_starttag(self, tag, attrs) -> None:
        if tag == "table":
            self.tables.append(([], []))
        elif tag == "thead":
            self._in_head = True
        elif tag == "tbody":
            self._in_head = False
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag) -> None:
        if tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell))
            self._cell = None
        elif tag == "tr":
            if self._in_head:
                self.tables[-1][0].extend(self._row)
            else:
                self.tables[-1][1].append(self._row)

    def handle_data(self, data) -> None:
        if self._cell is not None:
            self._cell.append(data)


def _expected_tables(results: ev.Results) -> list:
    from evaluation.reports.sections import controller_tables, leaderboard_rows, paired_rows

    tables = [leaderboard_rows(results)]
    if paired_rows(results)[1]:
        tables.append(paired_rows(results))
    tables += [table for _, table in controller_tables(results)]
    return [(list(h), [list(r) for r in rows]) for h, rows in tables]


# --------------------------------------------------------------------------- without a browser
def test_tables_are_the_reports_tables(run, page) -> None:
    results, _ = run
    parser = _Tables()
    parser.feed(page)
    assert parser.tables == _expected_tables(results)
    assert len(parser.tables) == 4  # leaderboard, paired comparisons, one per controller
    for label in results.config["controllers"]:
        assert sum(label in row for row in parser.tables[0][1]) == 1


def test_page_is_self_contained(page) -> None:
    assert not re.search(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//""", page, re.IGNORECASE)
    assert "http://" not in page and "https://" not in page
    assert "<link" not in page.lower()
    sources = re.findall(r"""\bsrc\s*=\s*["']([^"']*)""", page)
    assert sources and all(s.startswith("data:image/") for s in sources)
    assert all(h.startswith("#") for h in re.findall(r"""\bhref\s*=\s*["']([^"']*)""", page))
    assert "Content-Security-Policy" in page and "default-src 'none'" in page


def test_labels_are_escaped(run, page) -> None:
    assert XSS_LABEL not in page
    assert page.count("<script") == 1  # the page's own sorter
    assert "&lt;script&gt;x&lt;/script&gt;" in page
    assert render_html(run[0], run[1]).count("<script") == 1


def test_config_summary(page) -> None:
    command = "Regenerate with <code>python evaluate.py --controllers consensus --episodes 2</code>"
    for text in (
        "KoopNav-TargetReaching-v0",
        "map1",
        "nominal, high",
        "Episodes per cell",
        "1,000,000",
        command,
    ):
        assert text in page, text
    assert "consensus, goal_gain: 2" in page  # the options of the labelled configuration


def test_figures_and_animations_are_embedded(run, page) -> None:
    _, out = run
    figures = sorted((out / "figures").glob("*.png"))
    assert len(figures) == 5  # one trajectory per cell and the success-by-slip plot
    for path in figures:
        assert "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode() in page
    assert "data:image/gif;base64," + base64.b64encode(TINY_GIF).decode() in page
    assert "consensus | target reaching | map1 | high | trial 0" in page
    assert "animation animations/missing.gif not found" in page


# --------------------------------------------------------------------------- in a headless browser
@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.skip("no selenium: pip install -e '.[test]'")
    if not (CHROMIUM.is_file() and CHROMEDRIVER.is_file()):
        pytest.skip("no headless Chromium: apt install chromium chromium-driver")
    options = webdriver.ChromeOptions()
    # both paths given: selenium-manager is not asked to find (or download) anything
    options.binary_location = str(CHROMIUM)
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--window-size=1280,1600",
        f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}",
    ):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    yield driver
    driver.quit()


def _rows(table) -> list[list[str]]:
    from selenium.webdriver.common.by import By

    return [
        [td.text for td in tr.find_elements(By.TAG_NAME, "td")]
        for tr in table.find_elements(By.CSS_SELECTOR, "tbody tr")
    ]


def _number(text: str) -> float:
    return float(re.match(r"[<>]?\s*([+-]?\d+(?:\.\d+)?)", text).group(1))


def test_tables_render_and_nothing_is_fetched(browser, run) -> None:
    from selenium.webdriver.common.by import By

    results, out = run
    browser.get((out / "index.html").as_uri())
    tables = browser.find_elements(By.CSS_SELECTOR, "table.sortable")
    expected = _expected_tables(results)
    assert len(tables) == len(expected)
    for table, (header, rows) in zip(tables, expected):
        assert [th.text for th in table.find_elements(By.CSS_SELECTOR, "thead th")] == header
        assert _rows(table) == rows
    assert XSS_LABEL in [row[2] for row in _rows(tables[0])]  # shown as text, not run
    images = browser.find_elements(By.CSS_SELECTOR, "img")
    assert len(images) == 6  # 5 figures + 1 animation
    assert all(browser.execute_script("return arguments[0].naturalWidth", img) > 0 for img in images)
    assert browser.execute_script("return performance.getEntriesByType('resource').length") == 0
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, errors  # an unescaped label would have run as a script (ReferenceError: x)


def test_number_parsing_of_report_cells(browser, run) -> None:
    browser.get((run[1] / "index.html").as_uri())
    key = lambda text: browser.execute_script("return koopnavSortKey(arguments[0])", text)  # noqa: E731
    assert key("80% [49-94]") == pytest.approx(0.8)
    assert key("8/10 [49-94%]") == pytest.approx(0.8)
    assert key("12.3 [10.1-14.0]") == pytest.approx(12.3)
    assert key("12.3+-1.2") == pytest.approx(12.3)
    assert key("+5 [-3, +12]") == 5 and key("-12 [-20, -4]") == -12
    assert key("0 / 3") == 0 and key("1,000,000") == 1_000_000
    assert key("<0.001") < 0.001 < key("0.002")
    assert key("-") is None and key("") is None
    assert browser.execute_script("return isNaN(koopnavSortKey('map1'))")


def test_click_on_a_header_sorts_and_a_second_click_reverses(browser, run) -> None:
    from selenium.webdriver.common.by import By

    browser.get((run[1] / "index.html").as_uri())
    tables = browser.find_elements(By.CSS_SELECTOR, "table.sortable")
    table = tables[2]  # consensus: rows nominal, high
    headers = table.find_elements(By.CSS_SELECTOR, "thead th")
    col = [th.text for th in headers].index("team, collision-free [cm]")
    rows_before = _rows(table)
    before = [row[col] for row in rows_before]
    assert len(set(before)) == len(before) >= 2, before  # distinct values, so that an order shows

    headers[col].click()
    rows_ascending = _rows(table)
    ascending = [row[col] for row in rows_ascending]
    assert ascending == sorted(before, key=_number)
    assert headers[col].get_attribute("aria-sort") == "ascending"
    assert all(h.get_attribute("aria-sort") is None for i, h in enumerate(headers) if i != col)
    assert sorted(rows_ascending) == sorted(rows_before)  # whole rows move, not single cells

    headers[col].click()
    descending = [row[col] for row in _rows(table)]
    assert descending == sorted(before, key=_number, reverse=True) == ascending[::-1]
    assert headers[col].get_attribute("aria-sort") == "descending"
    assert ascending != before or descending != before  # one of the clicks changed the order

    # text columns sort as text; the previous header loses its mark
    slip = [th.text for th in headers].index("Slip")
    headers[slip].click()
    assert [row[slip] for row in _rows(table)] == ["high", "nominal"]
    assert headers[slip].get_attribute("aria-sort") == "ascending"
    assert headers[col].get_attribute("aria-sort") is None
    headers[slip].click()
    assert [row[slip] for row in _rows(table)] == ["nominal", "high"]

    # the leaderboard sorts by controller label, with the markup label as plain text
    board = tables[0]
    heads = board.find_elements(By.CSS_SELECTOR, "thead th")
    name = [th.text for th in heads].index("Controller")
    heads[name].click()
    labels = [row[name] for row in _rows(board)]
    assert labels == sorted(labels, key=str.lower)
    heads[name].click()
    assert [row[name] for row in _rows(board)] == labels[::-1]
