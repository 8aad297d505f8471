"""A parameters file's sections reach the nodes rcl gives them to, and a miss is said clearly."""

from conftest import run_domain_id
from followbot.parameters_file import (check_reaches, key_matches, ParametersFileError,
                                       read_sections)
import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node

KEYS = ['follower', '/follower', '/**', '/**/follower', '/*/follower', 'team/follower',
        '/team/*', '/team/**', '/**/r1/follower', '/team/r1/follower', 'sim']
NODES = ['/follower', '/team/follower', '/team/r1/follower', '/r1/follower']


def rcl_gives(tmp_path, key, fully_qualified_name) -> bool:
    """Return whether rcl gives a node of that name the parameters of a section with that key."""
    path = tmp_path / 'parameters.yaml'
    path.write_text(f'{key}:\n  ros__parameters:\n    probe: 7\n')
    namespace, _, name = fully_qualified_name.rpartition('/')
    context = Context()
    rclpy.init(args=['probe', '--ros-args', '--params-file', str(path)], context=context,
               domain_id=run_domain_id())
    try:
        node = Node(name, namespace=namespace or '/', context=context)
        value = node.declare_parameter('probe', 0).value
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    return value == 7


@pytest.mark.parametrize('fully_qualified_name', NODES)
def test_a_section_reaches_the_nodes_rcl_gives_it_to(tmp_path, fully_qualified_name):
    for key in KEYS:
        assert key_matches(key, fully_qualified_name) == rcl_gives(
            tmp_path, key, fully_qualified_name), (key, fully_qualified_name)


def test_a_file_that_misses_the_node_says_which_key_reaches_it(tmp_path):
    path = tmp_path / 'slow.yaml'
    path.write_text('follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n'
                    'followbot_sim:\n  ros__parameters:\n    camera_rate_hz: 30.0\n')
    assert read_sections(path) == ['follower', 'followbot_sim']
    check_reaches(path, '/follower')
    with pytest.raises(ParametersFileError) as error:
        check_reaches(path, '/r1/follower')
    assert str(error.value) == (
        f'Parameters file {path} gives nothing to the node /r1/follower: its sections '
        "('follower', 'followbot_sim') are for other nodes or namespaces. Name the section "
        "'/**/follower' to reach the follower in any namespace.")


@pytest.mark.parametrize('text, message', [
    (None, 'does not exist'),
    ('- 1\n', 'must map node names'),
    ('follower: [\n', 'not valid YAML'),
])
def test_a_file_that_is_no_parameters_file_is_refused(tmp_path, text, message):
    path = tmp_path / 'parameters.yaml'
    if text is not None:
        path.write_text(text)
    with pytest.raises(ParametersFileError, match=message):
        read_sections(path)
