"""
The scorecard's plots: how each configuration drove, as PNG pictures.

For every scenario, the distance from the line and the speed along the course, one curve per
configuration; over all scenarios, the lap times side by side. The plots are made from the run
records :mod:`followbot_sim.scorecard` gathers (``samples`` and ``metrics``), with matplotlib's
object interface and its Agg canvas: no display, no global pyplot state.
"""

from pathlib import Path
import re

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

# 800 x 450 pixels: readable on a docs page, a few tens of kilobytes each.
FIGURE_SIZE_IN = (8.0, 4.5)
DOTS_PER_INCH = 100
CM_PER_M = 100.0
LAP_TIMES_FILE = 'lap_times.png'
DISTANCE_FILE = 'distance_{scenario}.png'
SPEED_FILE = 'speed_{scenario}.png'
# A scenario named by a course file's path becomes a file name with these characters only.
UNSAFE_FILE_CHARACTERS = re.compile(r'[^A-Za-z0-9_.-]+')
CURVE_WIDTH = 1.2
# The lap-time axis reaches this far above the longest lap: room for the legend.
LEGEND_HEADROOM = 1.25


def _file_stem(scenario: str) -> str:
    return UNSAFE_FILE_CHARACTERS.sub('_', Path(scenario).stem if '/' in scenario else scenario)


def _new_figure(title: str, x_label: str, y_label: str):
    figure = Figure(figsize=FIGURE_SIZE_IN, dpi=DOTS_PER_INCH)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    axes.set_title(title)
    axes.set_xlabel(x_label)
    axes.set_ylabel(y_label)
    axes.grid(True, alpha=0.3)
    # The grid behind the curves and bars, not across them.
    axes.set_axisbelow(True)
    return figure, axes


def _save(figure, path: Path) -> Path:
    figure.tight_layout()
    figure.savefig(path, dpi=DOTS_PER_INCH)
    return path


def _runs_by_scenario(runs: list) -> dict:
    scenarios = {}
    for run in runs:
        scenarios.setdefault(run['scenario'], []).append(run)
    return scenarios


def plot_along_course(runs: list, column: str, scale: float, y_label: str, title: str,
                      path: Path) -> Path:
    """
    Plot one sampled figure of each run against its progress along the course.

    :param runs: run records of one scenario, each with ``configuration`` and ``samples``
        (columns ``progress_m`` and ``column``); runs without samples are left out.
    :param column: the sampled figure to plot, such as ``speed_mps``.
    :param scale: factor applied to its values (100 for metres shown in centimetres).
    :param y_label: the y axis' label, with the unit.
    :param title: the plot's title.
    :param path: the PNG file to write.
    :return: the path.
    """
    figure, axes = _new_figure(title, 'progress along the course (m)', y_label)
    for run in runs:
        samples = run.get('samples')
        if not samples or not samples['progress_m']:
            continue
        axes.plot(samples['progress_m'], [scale * value for value in samples[column]],
                  label=run['configuration'], linewidth=CURVE_WIDTH)
    if axes.has_data():
        axes.legend(loc='best')
    return _save(figure, path)


def plot_lap_times(runs: list, path: Path) -> Path:
    """
    Draw the lap time of each configuration on each scenario as grouped bars.

    :param runs: run records with ``scenario``, ``configuration`` and ``metrics`` (None after
        an error); a run without a lap gets no bar and a "no lap" mark.
    :param path: the PNG file to write.
    :return: the path.
    """
    scenarios = list(_runs_by_scenario(runs))
    configurations = list(dict.fromkeys(run['configuration'] for run in runs))
    figure, axes = _new_figure('Lap time per configuration', 'scenario', 'lap time (s)')
    bar_width = 0.8 / max(1, len(configurations))
    lap_s = {(run['scenario'], run['configuration']):
             (run.get('metrics') or {}).get('lap_time_s') for run in runs}
    for index, configuration in enumerate(configurations):
        offsets = [position + (index - (len(configurations) - 1) / 2.0) * bar_width
                   for position in range(len(scenarios))]
        heights = [lap_s.get((scenario, configuration)) for scenario in scenarios]
        bars = axes.bar(offsets, [height or 0.0 for height in heights], bar_width,
                        label=configuration)
        for bar, height in zip(bars, heights):
            label = f'{height:.0f}' if height else 'no lap'
            axes.annotate(label, (bar.get_x() + bar.get_width() / 2.0, bar.get_height()),
                          ha='center', va='bottom', fontsize=7, xytext=(0, 2),
                          textcoords='offset points')
    axes.set_xticks(range(len(scenarios)))
    axes.set_xticklabels([_file_stem(scenario) for scenario in scenarios], rotation=30,
                         ha='right', fontsize=8)
    axes.grid(False, axis='x')
    # Headroom above the tallest bar for the legend, in one row, and the bars' labels.
    highest_s = max((time_s for time_s in lap_s.values() if time_s), default=1.0)
    axes.set_ylim(0.0, LEGEND_HEADROOM * highest_s)
    axes.legend(loc='upper center', ncols=max(1, len(configurations)))
    return _save(figure, path)


def write_plots(runs: list, folder) -> list:
    """
    Write every plot of a scorecard into a folder.

    :param runs: the scorecard's run records.
    :param folder: where the PNG files go; made if missing.
    :return: the paths written: ``lap_times.png``, then ``distance_<scenario>.png`` and
        ``speed_<scenario>.png`` for each scenario.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [plot_lap_times(runs, folder / LAP_TIMES_FILE)]
    for scenario, scenario_runs in _runs_by_scenario(runs).items():
        stem = _file_stem(scenario)
        paths.append(plot_along_course(
            scenario_runs, 'distance_from_line_m', CM_PER_M, 'distance from the line (cm)',
            f'{scenario}: distance from the line', folder / DISTANCE_FILE.format(scenario=stem)))
        paths.append(plot_along_course(
            scenario_runs, 'speed_mps', 1.0, 'forward speed (m/s)', f'{scenario}: speed',
            folder / SPEED_FILE.format(scenario=stem)))
    return paths
