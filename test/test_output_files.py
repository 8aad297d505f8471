"""A file a command is to write is checked before any work: a bad path ends it in one line."""

import argparse

from followbot.output_files import (check_output_file, make_output_folder, output_file_option,
                                    OutputPathError)
import pytest


def test_a_file_in_an_existing_folder_can_be_written(tmp_path):
    assert check_output_file(tmp_path / 'run.json', 'the results') == tmp_path / 'run.json'
    assert check_output_file(str(tmp_path / 'view.PNG'), 'the picture', ('.png', '.jpg')) == (
        tmp_path / 'view.PNG')


@pytest.mark.parametrize('name, suffixes, message', [
    ('missing/run.json', (), 'folder {tmp}/missing does not exist.'),
    ('', (), 'it is a folder; give a file name.'),
    ('view.gif', ('.png',), 'the file name must end in .png.'),
    ('view.gif', ('.png', '.jpg', '.jpeg'), 'the file name must end in .png, .jpg or .jpeg.'),
])
def test_a_path_that_cannot_be_written_is_refused_saying_why(tmp_path, name, suffixes, message):
    path = tmp_path / name
    with pytest.raises(OutputPathError) as error:
        check_output_file(path, 'the results', suffixes)
    assert str(error.value) == (f'cannot write the results to {path}: '
                                + message.format(tmp=tmp_path))


def test_the_option_type_gives_argparse_the_same_sentence(tmp_path):
    option = output_file_option('the figures')
    assert option(str(tmp_path / 'b.json')) == tmp_path / 'b.json'
    with pytest.raises(argparse.ArgumentTypeError, match='does not exist'):
        option(str(tmp_path / 'missing' / 'b.json'))


def test_a_folder_to_write_into_is_made_with_its_parents(tmp_path):
    folder = tmp_path / 'runs' / 'today'
    assert make_output_folder(folder, 'the pictures') == folder
    assert folder.is_dir()
    assert make_output_folder(folder, 'the pictures') == folder


def test_a_file_in_the_way_of_a_folder_is_refused(tmp_path):
    (tmp_path / 'runs').write_text('a file')
    with pytest.raises(OutputPathError) as error:
        make_output_folder(tmp_path / 'runs', 'the pictures')
    assert str(error.value) == f'cannot write the pictures into {tmp_path}/runs: File exists.'
