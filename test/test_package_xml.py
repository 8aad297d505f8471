"""Check package.xml: REP-149 format 3, in step with setup.py, declaring every dependency."""

import ast
from pathlib import Path
import re
import sys

from catkin_pkg.package import parse_package
from conftest import PACKAGE_DIR
import pytest

pytestmark = pytest.mark.linter

PACKAGE_XML = PACKAGE_DIR / 'package.xml'
SETUP_PY = PACKAGE_DIR / 'setup.py'
REQUIREMENTS_TXT = PACKAGE_DIR / 'requirements.txt'
# The installed Python packages: their modules run with the exec_depends alone.
RUNTIME_DIRS = ('followbot', 'followbot_sim')
# The tests may use exec_depends and test_depends.
TEST_DIR = 'test'
# Rosdep key of each non-ROS library, by the top-level name the code imports. Any other import
# is a ROS package, which is its own rosdep key (rclpy, sensor_msgs, ament_flake8, ...).
LIBRARY_KEYS = {
    'catkin_pkg': 'python3-catkin-pkg-modules',
    'cv2': 'python3-opencv',
    'hypothesis': 'python3-hypothesis',
    'matplotlib': 'python3-matplotlib',
    'mcap': 'mcap-ros2-support',
    'mcap_ros2': 'mcap-ros2-support',
    'mujoco': 'python3-mujoco-pip',
    'numpy': 'python3-numpy',
    'pytest': 'python3-pytest',
    'rosbags': 'python3-rosbags-pip',
    'yaml': 'python3-yaml',
}
# Test dependencies no import shows, because the tests run them as commands.
TOOL_KEYS = {
    'libxml2-utils': 'test_xmllint.py runs its xmllint command on the XML files',
    'python3-colcon-common-extensions':
        'the colcon build test runs the colcon command in a temporary workspace',
}
# PyPI project (requirements.txt, the no-ROS route) of each non-ROS exec_depend. A ROS package
# key such as sensor_msgs is the community wheel ros-sensor-msgs.
LIBRARY_REQUIREMENTS = {
    'mcap-ros2-support': 'mcap-ros2-support',
    'python3-matplotlib': 'matplotlib',
    'python3-mujoco-pip': 'mujoco',
    'python3-numpy': 'numpy',
    'python3-opencv': 'opencv-python-headless',
    'python3-yaml': 'pyyaml',
}
# PyPI projects requirements.txt pins beside an exec_depend's own, because that package brings
# them: {project: rosdep key}.
PINNED_WITH = {'mcap': 'mcap-ros2-support'}
# A ROS package's name (REP-144); other rosdep keys (python3-..., lib...-dev) are system keys.
ROS_PACKAGE_NAME = r'[a-z][a-z0-9_]*'
# exec_depends with no wheel on PyPI: the no-ROS route runs without them.
NOT_ON_PYPI = {
    'tf2_msgs': 'make setup builds config/tf2_msgs, a TFMessage-only stand-in, into the venv',
}
# The setup() keywords that must say what package.xml says.
SHARED_METADATA = ('name', 'version', 'license', 'maintainer', 'maintainer_email')


def rosdep_key(module: str) -> str:
    """
    Return the rosdep key that provides a top-level Python module.

    :param module: the top-level name in an import statement, such as 'cv2'.
    :return: the key, such as 'python3-opencv'; a ROS package's own name for ROS modules.
    """
    return LIBRARY_KEYS.get(module, module)


def requirement_name(key: str):
    """
    Return the requirements.txt project name that stands for an exec_depend on PyPI.

    :param key: the rosdep key, such as 'sensor_msgs' or 'python3-numpy'.
    :return: the normalised PyPI name, such as 'ros-sensor-msgs' or 'numpy'; None for a system
        key missing from LIBRARY_REQUIREMENTS.
    """
    if key in LIBRARY_REQUIREMENTS:
        return LIBRARY_REQUIREMENTS[key]
    if re.fullmatch(ROS_PACKAGE_NAME, key):
        return 'ros-' + key.replace('_', '-')
    return None


def own_modules() -> set:
    """Return the top-level module names the package itself provides, tests included."""
    test_modules = {path.stem for path in (PACKAGE_DIR / TEST_DIR).glob('*.py')}
    return set(RUNTIME_DIRS) | test_modules


def imported_modules(source_path: Path) -> dict:
    """
    Return the top-level modules a Python file imports absolutely, with the first line of each.

    :param source_path: the Python file.
    :return: {top-level module name: line number of its first import}.
    """
    tree = ast.parse(source_path.read_text(encoding='utf-8'), filename=str(source_path))
    first_lines = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            modules = [node.module]
        else:
            continue
        for module in modules:
            top_level = module.split('.')[0]
            first_lines[top_level] = min(first_lines.get(top_level, node.lineno), node.lineno)
    return first_lines


def dependency_imports(directory: str) -> list:
    """
    Return every import of a directory's Python files that needs a declared dependency.

    The standard library and the package's own modules need none.

    :param directory: the directory, relative to the package.
    :return: (file:line, module, rosdep key) tuples, sorted.
    """
    needless = set(sys.stdlib_module_names) | own_modules()
    found = []
    for source_path in sorted((PACKAGE_DIR / directory).rglob('*.py')):
        location = source_path.relative_to(PACKAGE_DIR).as_posix()
        for module, line in sorted(imported_modules(source_path).items()):
            if module not in needless:
                found.append((f'{location}:{line}', module, rosdep_key(module)))
    return found


def requirement_names(requirements_path: Path) -> set:
    """
    Return the normalised project names a requirements file lists, without included files.

    :param requirements_path: the requirements file.
    :return: names such as 'ros-rclpy' (for 'ros-rclpy[fastrtps]==7.1.6').
    """
    names = set()
    for line in requirements_path.read_text(encoding='utf-8').splitlines():
        requirement = line.split('#', 1)[0].strip()
        if requirement and not requirement.startswith('-'):
            project = re.match(r'[A-Za-z0-9][A-Za-z0-9._-]*', requirement).group(0)
            names.add(re.sub(r'[-_.]+', '-', project).lower())
    return names


def setup_keywords() -> dict:
    """
    Return the literal keyword arguments of setup.py's setup() call, without running setup.py.

    A keyword given as a module-level constant (name=package_name) counts as that constant.

    :return: {keyword: value} for every keyword whose value is a literal or such a constant.
    """
    tree = ast.parse(SETUP_PY.read_text(encoding='utf-8'), filename=str(SETUP_PY))
    constants = {}
    for node in tree.body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name)):
            try:
                constants[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass
    setup_calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call)
                   and isinstance(node.func, ast.Name) and node.func.id == 'setup']
    assert len(setup_calls) == 1, f'setup.py calls setup() {len(setup_calls)} times, not once'
    keywords = {}
    for keyword in setup_calls[0].keywords:
        if isinstance(keyword.value, ast.Name) and keyword.value.id in constants:
            keywords[keyword.arg] = constants[keyword.value.id]
            continue
        try:
            keywords[keyword.arg] = ast.literal_eval(keyword.value)
        except ValueError:
            pass
    return keywords


@pytest.fixture(scope='module')
def package():
    """Return package.xml as catkin_pkg reads it."""
    return parse_package(str(PACKAGE_XML))


def test_package_xml_is_valid_format_3_without_warnings():
    parse_warnings = []
    package = parse_package(str(PACKAGE_XML), warnings=parse_warnings)
    validate_warnings = []
    package.validate(warnings=validate_warnings)
    assert parse_warnings == []
    assert validate_warnings == []
    assert package.package_format == 3
    assert package.name == 'followbot'


def test_package_builds_as_ament_python(package):
    assert package.get_build_type() == 'ament_python'


@pytest.mark.parametrize('keyword', SHARED_METADATA)
def test_setup_py_says_what_package_xml_says(package, keyword):
    package_xml_metadata = {
        'name': package.name,
        'version': package.version,
        'license': ', '.join(package.licenses),
        'maintainer': ', '.join(maintainer.name for maintainer in package.maintainers),
        'maintainer_email': ', '.join(maintainer.email for maintainer in package.maintainers),
    }
    keywords = setup_keywords()
    assert keyword in keywords, f'setup.py gives setup() no literal {keyword}='
    assert keywords[keyword] == package_xml_metadata[keyword], (
        f'setup.py says {keyword}={keywords[keyword]!r}, '
        f'package.xml says {package_xml_metadata[keyword]!r}')


def test_setup_py_description_is_a_one_line_summary(package):
    # package.xml has the full description; setup.py's is its short, single-line form.
    description = setup_keywords().get('description', '')
    assert package.description.strip()
    assert description.strip()
    assert '\n' not in description


def test_runtime_imports_are_exec_depends(package):
    exec_keys = {dependency.name for dependency in package.exec_depends}
    missing = [f'{location} imports {module}, but package.xml has no '
               f'<exec_depend>{key}</exec_depend>'
               for directory in RUNTIME_DIRS
               for location, module, key in dependency_imports(directory)
               if key not in exec_keys]
    assert missing == [], '\n'.join(missing)


def test_test_imports_are_declared(package):
    declared_keys = {dependency.name
                     for dependency in package.exec_depends + package.test_depends}
    missing = [f'{location} imports {module}, but package.xml has neither '
               f'<test_depend>{key}</test_depend> nor <exec_depend>{key}</exec_depend>'
               for location, module, key in dependency_imports(TEST_DIR)
               if key not in declared_keys]
    assert missing == [], '\n'.join(missing)


def test_every_exec_depend_is_imported_by_the_runtime_code(package):
    imported_keys = {key for directory in RUNTIME_DIRS
                     for _, _, key in dependency_imports(directory)}
    unused = [f'package.xml declares <exec_depend>{dependency.name}</exec_depend>, '
              f'but no module in {" or ".join(RUNTIME_DIRS)} imports it'
              for dependency in package.exec_depends if dependency.name not in imported_keys]
    assert unused == [], '\n'.join(unused)


def test_every_test_depend_is_imported_by_the_tests_or_run_as_a_tool(package):
    imported_keys = {key for _, _, key in dependency_imports(TEST_DIR)}
    unused = [f'package.xml declares <test_depend>{dependency.name}</test_depend>, '
              f'but no module in {TEST_DIR}/ imports it'
              for dependency in package.test_depends
              if dependency.name not in imported_keys | set(TOOL_KEYS)]
    assert unused == [], '\n'.join(unused)


def test_every_tool_dependency_is_a_test_depend(package):
    test_keys = {dependency.name for dependency in package.test_depends}
    assert set(TOOL_KEYS) <= test_keys, (
        f'TOOL_KEYS names {sorted(set(TOOL_KEYS) - test_keys)}, which package.xml does not '
        'declare as <test_depend>: declare them, or drop them from TOOL_KEYS')


def test_requirements_txt_pins_every_exec_depend_on_pypi(package):
    requirements = requirement_names(REQUIREMENTS_TXT)
    unmapped = [f'package.xml declares <exec_depend>{dependency.name}</exec_depend>, a system '
                'key: add its PyPI project to LIBRARY_REQUIREMENTS'
                for dependency in package.exec_depends
                if requirement_name(dependency.name) is None]
    assert unmapped == [], '\n'.join(unmapped)
    missing = [f'package.xml declares <exec_depend>{dependency.name}</exec_depend>, but '
               f'requirements.txt has no {requirement_name(dependency.name)}'
               for dependency in package.exec_depends
               if dependency.name not in NOT_ON_PYPI
               and requirement_name(dependency.name) not in requirements]
    assert missing == [], '\n'.join(missing)


def test_requirements_txt_pins_nothing_package_xml_lacks(package):
    exec_keys = {dependency.name for dependency in package.exec_depends}
    expected = {requirement_name(key) for key in exec_keys}
    expected |= {project for project, key in PINNED_WITH.items() if key in exec_keys}
    extra = [f'requirements.txt lists {name}, which stands for no <exec_depend> of package.xml'
             for name in sorted(requirement_names(REQUIREMENTS_TXT) - expected)]
    assert extra == [], '\n'.join(extra)


@pytest.mark.parametrize('key', sorted(NOT_ON_PYPI))
def test_not_on_pypi_exceptions_are_current(package, key):
    assert key in {dependency.name for dependency in package.exec_depends}, (
        f'NOT_ON_PYPI names {key}, which is no <exec_depend> of package.xml')
    assert requirement_name(key) not in requirement_names(REQUIREMENTS_TXT), (
        f'requirements.txt now pins {requirement_name(key)}: drop {key} from NOT_ON_PYPI')
