"""The README is a front page, and the documentation says what the code does."""

from pathlib import Path
import re

from followbot.follower_node import FOLLOWER_PARAMETERS
from followbot_sim.sim_node import SIMULATOR_PARAMETERS
import pytest

PACKAGE_DIR = Path(__file__).resolve().parent.parent
README = PACKAGE_DIR / 'README.md'
DOCS_DIR = PACKAGE_DIR / 'docs'
MAX_README_LINES = 250
# [text](target) in Markdown, outside code.
LINK = re.compile(r'\]\(([^)\s]+)\)')
PAGES = [README, *sorted(DOCS_DIR.glob('*.md'))]


def anchors(page: Path) -> set:
    """Return the heading anchors of a Markdown page, as GitHub makes them."""
    found = set()
    in_code = False
    for line in page.read_text().splitlines():
        if line.startswith('```'):
            in_code = not in_code
        elif not in_code and line.startswith('#'):
            title = line.lstrip('#').strip().lower()
            found.add(re.sub(r'[^\w\- ]', '', title).replace(' ', '-'))
    return found


def test_the_readme_is_a_front_page():
    assert len(README.read_text().splitlines()) < MAX_README_LINES


@pytest.mark.parametrize('page', PAGES, ids=[page.name for page in PAGES])
def test_every_link_leads_somewhere(page):
    text = re.sub(r'```.*?```', '', page.read_text(), flags=re.DOTALL)
    for target in LINK.findall(text):
        if re.match(r'[a-z]+://', target):
            continue
        path, _, anchor = target.partition('#')
        linked = (page.parent / path).resolve() if path else page
        assert linked.exists(), f'{page.name}: {target} does not exist'
        if anchor and linked.suffix == '.md':
            assert anchor in anchors(linked), f'{page.name}: no heading for {target}'


@pytest.mark.parametrize('page, parameters', [
    ('follower.md', FOLLOWER_PARAMETERS), ('simulator.md', SIMULATOR_PARAMETERS)])
def test_every_parameter_is_documented_with_its_default(page, parameters):
    rows = {}
    for line in (DOCS_DIR / page).read_text().splitlines():
        cells = [cell.strip() for cell in line.strip('|').split('|')]
        if line.startswith('| `') and len(cells) >= 2:
            rows[cells[0].strip('`')] = cells[1].strip('`')
    for name, spec in parameters.items():
        assert name in rows, f'{page} does not document {name}'
        default = spec.default
        if isinstance(default, bool):
            expected = 'true' if default else 'false'
        elif isinstance(default, float):
            expected = f'{default:g}'
        elif isinstance(default, str) and not default:
            expected = '""'
        else:
            expected = str(default)
        if not isinstance(default, (list, tuple)):
            assert rows[name] == expected, f'{page}: {name} documented as {rows[name]}'
