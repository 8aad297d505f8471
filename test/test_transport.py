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
    assert in_force == str(transport.fastdds_profile_path())
    assert with_profile == {'PATH': '/usr/bin', transport.FASTDDS_PROFILE_VARIABLE: in_force}
    assert environment.get(transport.FASTDDS_PROFILE_VARIABLE) == chosen


def test_a_profile_the_user_chose_is_kept():
    environment = {transport.FASTDDS_PROFILE_VARIABLE: '/etc/my_fastdds.xml'}
    with_profile, in_force = transport.environment_with_profile(environment)
    assert in_force == '/etc/my_fastdds.xml'
    assert with_profile == environment


def test_environment_without_profile_uses_fastdds_defaults():
    environment = {'PATH': '/usr/bin', transport.FASTDDS_PROFILE_VARIABLE: '/x.xml'}
    assert transport.environment_without_profile(environment) == {'PATH': '/usr/bin'}


def test_keep_large_buffers_tunes_glibc(monkeypatch):
    monkeypatch.delenv('MALLOC_MMAP_THRESHOLD_', raising=False)
    assert transport.keep_large_buffers() is True


def test_keep_large_buffers_leaves_a_users_malloc_settings_alone(monkeypatch):
    monkeypatch.setenv('MALLOC_MMAP_THRESHOLD_', '1048576')
    assert transport.keep_large_buffers() is False
