"""The Fast DDS profile for images and the allocator settings that keep frames fast."""

import xml.etree.ElementTree as ElementTree

from followbot import transport
import pytest

FASTDDS_NAMESPACE = {'dds': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
# The largest image the simulator makes (1280x1280 rgb8), and a 640x480 frame with room for
# the frames in flight to several subscribers.
LARGEST_IMAGE_BYTES = 1280 * 1280 * 3
FRAMES_IN_FLIGHT = 16
VGA_FRAME_BYTES = 640 * 480 * 3


@pytest.fixture(scope='module')
def profile():
    return ElementTree.parse(transport.fastdds_profile_path()).getroot()


def test_profile_gives_participants_a_shared_memory_segment_large_enough_for_images(profile):
    shared_memory = [descriptor for descriptor in profile.iterfind(
        'dds:profiles/dds:transport_descriptors/dds:transport_descriptor', FASTDDS_NAMESPACE)
        if descriptor.findtext('dds:type', namespaces=FASTDDS_NAMESPACE) == 'SHM']
    assert len(shared_memory) == 1
    segment_bytes = int(shared_memory[0].findtext('dds:segment_size',
                                                  namespaces=FASTDDS_NAMESPACE))
    assert segment_bytes >= LARGEST_IMAGE_BYTES
    assert segment_bytes >= FRAMES_IN_FLIGHT * VGA_FRAME_BYTES


def test_profile_is_the_default_and_keeps_udp_for_other_machines(profile):
    participant = profile.find('dds:profiles/dds:participant', FASTDDS_NAMESPACE)
    assert participant.get('is_default_profile') == 'true'
    used = {element.text for element in participant.iterfind(
        'dds:rtps/dds:userTransports/dds:transport_id', FASTDDS_NAMESPACE)}
    types = {descriptor.findtext('dds:transport_id', namespaces=FASTDDS_NAMESPACE):
             descriptor.findtext('dds:type', namespaces=FASTDDS_NAMESPACE)
             for descriptor in profile.iterfind(
                 'dds:profiles/dds:transport_descriptors/dds:transport_descriptor',
                 FASTDDS_NAMESPACE)}
    assert sorted(types[name] for name in used) == ['SHM', 'UDPv4']
    # Without this Fast DDS would add its own small segment beside the declared one.
    assert participant.findtext('dds:rtps/dds:useBuiltinTransports',
                                namespaces=FASTDDS_NAMESPACE) == 'false'


@pytest.mark.parametrize('chosen', [None, ''])
def test_environment_gets_the_profile_when_none_is_chosen(chosen):
    environment = {'PATH': '/usr/bin'}
    if chosen is not None:
        environment[transport.FASTDDS_PROFILE_VARIABLE] = chosen
    with_profile, in_force = transport.environment_with_profile(environment)
    path = str(transport.fastdds_profile_path())
    assert in_force == f'profile {path}'
    assert with_profile == {'PATH': '/usr/bin', transport.FASTDDS_PROFILE_VARIABLE: path}
    assert environment.get(transport.FASTDDS_PROFILE_VARIABLE) == chosen


def test_a_profile_the_user_chose_is_kept():
    environment = {transport.FASTDDS_PROFILE_VARIABLE: '/etc/my_fastdds.xml'}
    with_profile, in_force = transport.environment_with_profile(environment)
    assert in_force == 'configuration of yours, FASTRTPS_DEFAULT_PROFILES_FILE=/etc/my_fastdds.xml'
    assert with_profile == environment


def test_environment_without_profile_asks_for_fastdds_defaults():
    environment = {'PATH': '/usr/bin', transport.FASTDDS_PROFILE_VARIABLE: '/x.xml'}
    assert transport.environment_without_profile(environment) == {
        'PATH': '/usr/bin', 'FASTDDS_BUILTIN_TRANSPORTS': 'DEFAULT'}


@pytest.mark.parametrize('variable', transport.USER_CONFIGURATION_VARIABLES)
def test_any_fastdds_variable_of_the_users_is_their_configuration(variable, tmp_path):
    assert transport.users_fastdds_configuration({variable: 'X'}, tmp_path) == f'{variable}=X'


@pytest.mark.parametrize('name', transport.WORKING_DIRECTORY_PROFILES)
def test_a_profile_file_in_the_working_directory_is_the_users(name, tmp_path):
    (tmp_path / name).write_text('<dds/>')
    assert transport.users_fastdds_configuration({}, tmp_path) == str(tmp_path / name)


def test_another_middleware_needs_no_fastdds_profile(tmp_path):
    environment = {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}
    assert transport.users_fastdds_configuration(environment, tmp_path) == transport.NOT_FASTDDS


def test_nodes_take_the_package_profile_when_the_user_has_none(monkeypatch, tmp_path):
    for variable in (*transport.USER_CONFIGURATION_VARIABLES, 'RMW_IMPLEMENTATION'):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.chdir(tmp_path)
    line = transport.use_package_profile()
    path = str(transport.fastdds_profile_path())
    assert transport.os.environ[transport.FASTDDS_PROFILE_VARIABLE] == path
    assert line.startswith(f"Fast DDS configuration: followbot's profile {path}")
    assert '\n' not in line


def test_nodes_keep_the_users_fastdds_configuration(monkeypatch, tmp_path):
    monkeypatch.setenv('FASTDDS_BUILTIN_TRANSPORTS', 'LARGE_DATA')
    monkeypatch.delenv(transport.FASTDDS_PROFILE_VARIABLE, raising=False)
    monkeypatch.chdir(tmp_path)
    assert transport.use_package_profile() == (
        'Fast DDS configuration: yours (FASTDDS_BUILTIN_TRANSPORTS=LARGE_DATA).')
    assert transport.FASTDDS_PROFILE_VARIABLE not in transport.os.environ


def test_keep_large_buffers_tunes_glibc(monkeypatch):
    monkeypatch.delenv('MALLOC_MMAP_THRESHOLD_', raising=False)
    assert transport.keep_large_buffers() is True


def test_keep_large_buffers_leaves_a_users_malloc_settings_alone(monkeypatch):
    monkeypatch.setenv('MALLOC_MMAP_THRESHOLD_', '1048576')
    assert transport.keep_large_buffers() is False


def test_the_package_profile_exported_by_the_launcher_is_named_as_the_packages(monkeypatch,
                                                                              tmp_path):
    for variable in (*transport.USER_CONFIGURATION_VARIABLES, 'RMW_IMPLEMENTATION'):
        monkeypatch.delenv(variable, raising=False)
    path = str(transport.fastdds_profile_path())
    monkeypatch.setenv(transport.FASTDDS_PROFILE_VARIABLE, path)
    monkeypatch.chdir(tmp_path)
    assert transport.use_package_profile().startswith(
        f"Fast DDS configuration: followbot's profile {path}")
