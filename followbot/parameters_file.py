"""
ROS 2 parameters files: read one, and tell which of its sections reach a node.

rcl gives a node every section whose key matches its fully qualified name: a key without a
leading slash counts from the root (``follower`` is ``/follower``), ``*`` stands for one name
and ``**`` for any number of them (``/**/follower`` is a follower in any namespace); partial
names (``foll*``) are not wildcards. A file written for ``ros2 run followbot follower`` with a
``follower:`` section therefore gives nothing to a follower under a namespace, and rcl says
nothing: the follower runs on its defaults. The commands that run a follower under a namespace
of their own (a replay, raced robots) check that the user's file reaches it.
"""

from pathlib import Path

import yaml

# The section key that reaches a node of this name in any namespace.
ANY_NAMESPACE_KEY = '/**/{name}'


class ParametersFileError(ValueError):
    """A parameters file that cannot be read, or that gives a node nothing."""


def read_sections(path) -> list:
    """
    Read a parameters file and return its section keys (node names), in file order.

    :param path: the YAML file.
    :return: the keys as strings.
    :raises ParametersFileError: if the file is missing, unreadable, not YAML or not a mapping
        of node names to sections.
    """
    path = Path(path)
    try:
        document = yaml.safe_load(path.read_text(encoding='utf-8'))
    except FileNotFoundError:
        raise ParametersFileError(f'Parameters file {path} does not exist.') from None
    except (OSError, UnicodeDecodeError) as error:
        raise ParametersFileError(f'Cannot read parameters file {path}: {error}.') from None
    except yaml.YAMLError as error:
        raise ParametersFileError(f'Parameters file {path} is not valid YAML: '
                                  f'{" ".join(str(error).split())}') from None
    if not isinstance(document, dict):
        raise ParametersFileError(f'Parameters file {path} must map node names to '
                                  '{ros__parameters: {...}}, as ROS 2 parameters files do.')
    return [str(key) for key in document]


def key_matches(key: str, fully_qualified_name: str) -> bool:
    """
    Tell whether a parameters file's section key reaches a node, as rcl matches them.

    :param key: the section's key (``follower``, ``/robot1/follower``, ``/**``, ...).
    :param fully_qualified_name: the node's name with its namespace (``/robot1/follower``).
    :return: whether the node takes the section's parameters.
    """
    return _tokens_match(key.strip('/').split('/'), fully_qualified_name.strip('/').split('/'))


def _tokens_match(pattern: list, names: list) -> bool:
    if not pattern:
        return not names
    if pattern[0] == '**':
        return any(_tokens_match(pattern[1:], names[start:])
                   for start in range(len(names) + 1))
    return (bool(names) and pattern[0] in ('*', names[0])
            and _tokens_match(pattern[1:], names[1:]))


def check_reaches(path, fully_qualified_name: str) -> None:
    """
    Check that a parameters file gives a node parameters.

    :param path: the YAML file.
    :param fully_qualified_name: the node's name with its namespace.
    :raises ParametersFileError: as :func:`read_sections` does, or, when no section reaches
        the node, saying which nodes the file's sections are for and which key reaches it.
    """
    keys = read_sections(path)
    if any(key_matches(key, fully_qualified_name) for key in keys):
        return
    name = fully_qualified_name.rstrip('/').rpartition('/')[2]
    sections = ', '.join(repr(key) for key in keys) or 'none'
    raise ParametersFileError(
        f'Parameters file {path} gives nothing to the node {fully_qualified_name}: its sections '
        f'({sections}) are for other nodes or namespaces. Name the section '
        f"'{ANY_NAMESPACE_KEY.format(name=name)}' to reach the {name} in any namespace.")
