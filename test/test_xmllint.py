"""Check every XML file of the package with libxml2's xmllint, and Fast DDS profiles' schema."""

import os
from pathlib import Path
import shutil
import subprocess
import sys

from conftest import PACKAGE_DIR
import pytest

pytestmark = [pytest.mark.linter, pytest.mark.xmllint]

# Directories holding no package files: colcon's output when a workspace is built in the
# checkout, and caches. Hidden directories (.git, .venv) and virtual environments are skipped too.
SKIPPED_DIRS = {'build', 'install', 'log', '__pycache__'}
# Fast DDS reads the profiles in this directory (FASTRTPS_DEFAULT_PROFILES_FILE).
FASTDDS_PROFILE_DIR = 'config'
# Fast DDS 2.x (Jazzy) installs its profile schema as <prefix>/share/<this name>.
FASTDDS_SCHEMA_NAME = 'fastRTPS_profiles.xsd'
# The Debian package (and rosdep key) that provides the xmllint command.
XMLLINT_PACKAGE = 'libxml2-utils'
# A hung xmllint fails its test instead of stalling the whole run.
XMLLINT_TIMEOUT_S = 60.0
# An element the Fast DDS schema does not know, for the schema check's negative case.
UNKNOWN_ELEMENT_NAME = 'followbot_unknown_setting'


def package_xml_files() -> list:
    """Return every XML file of the package, sorted, outside hidden and generated directories."""
    found = []
    for directory, subdirectories, file_names in os.walk(PACKAGE_DIR):
        subdirectories[:] = sorted(
            name for name in subdirectories
            if not name.startswith('.') and name not in SKIPPED_DIRS
            and not Path(directory, name, 'pyvenv.cfg').exists())
        found.extend(Path(directory, name) for name in sorted(file_names)
                     if name.endswith('.xml'))
    return found


def package_path(path: Path) -> str:
    """
    Return a file's path relative to the package, for test ids and messages.

    :param path: a file inside the package.
    :return: the relative path with forward slashes, such as 'config/fastdds_shm.xml'.
    """
    return path.relative_to(PACKAGE_DIR).as_posix()


def find_fastdds_schema():
    """
    Return Fast DDS's profile schema, searched in the ament prefixes and this Python's prefix.

    :return: the schema's path, or None when no prefix has it.
    """
    prefixes = [prefix for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                if prefix]
    for prefix in prefixes + [sys.prefix]:
        candidate = Path(prefix, 'share', FASTDDS_SCHEMA_NAME)
        if candidate.is_file():
            return candidate
    return None


def run_xmllint(xmllint: str, *arguments) -> subprocess.CompletedProcess:
    """
    Run xmllint without output of the document and without network access.

    :param xmllint: the xmllint executable.
    :param arguments: further options and the files to check.
    :return: the finished process, with its text output captured.
    """
    return subprocess.run([xmllint, '--noout', '--nonet', *map(str, arguments)],
                          capture_output=True, text=True, timeout=XMLLINT_TIMEOUT_S)


XML_FILES = package_xml_files()
FASTDDS_PROFILES = sorted((PACKAGE_DIR / FASTDDS_PROFILE_DIR).glob('*.xml'))


@pytest.fixture(scope='module')
def xmllint():
    """Return the xmllint executable; skip when it is not installed."""
    executable = shutil.which('xmllint')
    if executable is None:
        pytest.skip(f'xmllint is not on PATH: install the Debian package {XMLLINT_PACKAGE}')
    return executable


@pytest.fixture(scope='module')
def fastdds_schema():
    """Return Fast DDS's profile schema; skip when no prefix has it."""
    schema = find_fastdds_schema()
    if schema is None:
        pytest.skip(f'Fast DDS schema {FASTDDS_SCHEMA_NAME} is not in share/ of any '
                    f'AMENT_PREFIX_PATH prefix nor of {sys.prefix}')
    return schema


def test_the_search_finds_the_package_files():
    # An empty search would leave the checks below with no cases, silently.
    assert PACKAGE_DIR / 'package.xml' in XML_FILES
    assert FASTDDS_PROFILES
    assert set(FASTDDS_PROFILES) <= set(XML_FILES)


@pytest.mark.parametrize('path', XML_FILES, ids=package_path)
def test_xml_file_is_well_formed(xmllint, path):
    result = run_xmllint(xmllint, path)
    assert result.returncode == 0, (
        f'xmllint rejects {package_path(path)}:\n{result.stdout}{result.stderr}')


@pytest.mark.parametrize('profile', FASTDDS_PROFILES, ids=package_path)
def test_fastdds_profile_matches_the_fastdds_schema(xmllint, fastdds_schema, profile):
    result = run_xmllint(xmllint, '--schema', fastdds_schema, profile)
    assert result.returncode == 0, (
        f'{package_path(profile)} does not match {fastdds_schema}:\n'
        f'{result.stdout}{result.stderr}')


@pytest.mark.parametrize(('intact', 'broken'), [
    ('</package>', '</package'),
    ('</name>', '</nam>'),
], ids=['unterminated closing tag', 'mismatched closing tag'])
def test_xmllint_rejects_a_malformed_copy(xmllint, tmp_path, intact, broken):
    text = (PACKAGE_DIR / 'package.xml').read_text(encoding='utf-8')
    assert intact in text
    malformed = tmp_path / 'package.xml'
    malformed.write_text(text.replace(intact, broken, 1), encoding='utf-8')
    result = run_xmllint(xmllint, malformed)
    assert result.returncode != 0
    assert str(malformed) in result.stderr


@pytest.mark.parametrize('profile', FASTDDS_PROFILES, ids=package_path)
def test_schema_rejects_a_profile_with_an_unknown_element(xmllint, fastdds_schema, tmp_path,
                                                          profile):
    text = profile.read_text(encoding='utf-8')
    assert '<profiles>' in text
    unknown = tmp_path / profile.name
    unknown.write_text(text.replace('<profiles>', f'<profiles><{UNKNOWN_ELEMENT_NAME}/>', 1),
                       encoding='utf-8')
    assert run_xmllint(xmllint, unknown).returncode == 0
    result = run_xmllint(xmllint, '--schema', fastdds_schema, unknown)
    assert result.returncode != 0
    assert UNKNOWN_ELEMENT_NAME in result.stderr
