"""
Files a command writes: checked before any work, so that a bad path costs no run.

A scorecard writes its JSON after minutes of runs and calibrate its picture after the whole
calibration: a file name they cannot write must end the command at once, in one line, not
in a traceback at the end with the work lost.
"""

import argparse
import os
from pathlib import Path


class OutputPathError(ValueError):
    """A file that cannot be written: a file type not written, a folder, a missing folder."""


def check_output_file(path, what: str, suffixes=()) -> Path:
    """
    Check that a file can be written at a path, before any work starts.

    :param path: the file to write; an existing file will be replaced.
    :param what: what is written, for the message ('a video', 'the JSON').
    :param suffixes: the file name endings (lower case, with the dot) of the types written;
        any when empty.
    :return: the path, as a Path.
    :raises OutputPathError: with one sentence, for another file type, a folder, a missing
        folder or one this user cannot write to.
    """
    path = Path(path)
    start = f'cannot write {what} to {path}:'
    if suffixes and path.suffix.lower() not in suffixes:
        endings = ', '.join(suffixes[:-1]) + ' or ' if len(suffixes) > 1 else ''
        raise OutputPathError(f'{start} the file name must end in {endings}{suffixes[-1]}.')
    if path.is_dir():
        raise OutputPathError(f'{start} it is a folder; give a file name.')
    folder = path.parent
    if not folder.is_dir():
        raise OutputPathError(f'{start} folder {folder} does not exist.')
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise OutputPathError(f'{start} permission denied.')
    return path


def make_output_folder(path, what: str) -> Path:
    """
    Make the folder a command writes files into (and its parents), before any work starts.

    :param path: the folder; it may exist already.
    :param what: what goes into it, for the message ('the pictures').
    :return: the path, as a Path.
    :raises OutputPathError: with one sentence, for a file in the way or a folder this user
        cannot make or write to.
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputPathError(f'cannot write {what} into {path}: '
                              f'{error.strerror or error}.') from None
    if not os.access(path, os.W_OK):
        raise OutputPathError(f'cannot write {what} into {path}: permission denied.')
    return path


def output_file_option(what: str, suffixes=()):
    """
    Return an argparse ``type`` for an option naming a file to write (see check_output_file).

    :param what: what is written, for the message.
    :param suffixes: the file name endings accepted; any when empty.
    :return: the function argparse calls with the option's text.
    """
    return _option(check_output_file, what, suffixes)


def output_folder_option(what: str):
    """
    Return an argparse ``type`` for an option naming a folder to write into.

    The folder is made as the command line is read (see make_output_folder).

    :param what: what goes into it, for the message.
    :return: the function argparse calls with the option's text.
    """
    return _option(make_output_folder, what)


def _option(check, what: str, *arguments):
    """Return an argparse ``type`` calling ``check(text, what, *arguments)``."""
    def read(text: str) -> Path:
        try:
            return check(text, what, *arguments)
        except OutputPathError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    read.__name__ = what
    return read
