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


def output_file_option(what: str, suffixes=()):
    """
    Return an argparse ``type`` for an option naming a file to write (see check_output_file).

    :param what: what is written, for the message.
    :param suffixes: the file name endings accepted; any when empty.
    :return: the function argparse calls with the option's text.
    """
    def read(text: str) -> Path:
        try:
            return check_output_file(text, what, suffixes)
        except OutputPathError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    read.__name__ = what
    return read
