"""The jobs on files (train, plot, info, eval), typed like :mod:`limbctl.jobs`; ``info``
without a file describes the bus."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

from limbctl.errors import ConfigError, FileFormatError
from limbctl.jobs import Connection, open_connection, prepare, say


@dataclass(frozen=True)
class TrainOptions:
    """``limbctl train``: the command line's options."""

    data: Path
    out: Path
    kind: str = "rigidmap"
    nodes: int | None = None
    layout: str | None = None
    seed: int = 0
    plot: Path | None = None


def model_options(kind: str, seed: int, **chosen: object) -> dict[str, object]:
    """Constructor keywords for a model of ``kind``: the seed where it takes one, each ``chosen``
    option not None.

    Raises
    ------
    ConfigError
        For an unknown kind, or an option the kind does not take.
    """
    from limbctl.envelope import model_class, model_kinds

    settable = model_class(kind).settable
    given = {name: value for name, value in chosen.items() if value is not None}
    if set(given) - set(settable):
        takers = [k for k in model_kinds() if set(chosen) <= set(model_class(k).settable)]
        flags = " and ".join(f"--{name}" for name in chosen)
        raise ConfigError(f"{flags} apply to --kind {' or '.join(takers)} only")
    return {"seed": seed, **given} if "seed" in settable else given


def run_train(options: TrainOptions) -> int:
    """Fit the model, save it, print its summary (and draw it with ``plot``)."""
    from tqdm import tqdm

    from limbctl.geometry.jit import mark_prepared, stage
    from limbctl.teach.dataset import load_dataset
    from limbctl.teach.train import STAGES, learns_twist, train

    constructor = model_options(
        options.kind, options.seed, nodes=options.nodes, layout=options.layout
    )
    # a three-servo recording compiles the twist band's kernels: a stage of its own
    twist = learns_twist(options.kind, load_dataset(options.data).header.calibration)
    prepare(stage("train", twist))
    with tqdm(
        total=len(STAGES), desc=f"training {options.kind}", unit="stage", file=sys.stderr
    ) as bar:

        def advance(finished: str) -> None:
            following = STAGES.index(finished) + 1
            bar.set_postfix_str(STAGES[following] if following < len(STAGES) else "done")
            bar.update(1)

        summary = train(options.data, options.out, options.kind, constructor, progress=advance)
    mark_prepared(stage("train", twist))
    for line in summary.lines():
        say(line)
    say(f"wrote {options.out}")
    if options.plot is not None:
        plot_files([options.data, options.out], options.plot)
        say(f"wrote {options.plot}")
    return 0


def plot_files(paths: list[Path], out: Path) -> Path:
    """Draw the models and datasets among ``paths`` (told apart by content) to PNG ``out``."""
    from limbctl.envelope import load_model
    from limbctl.plot import plot
    from limbctl.teach.dataset import load_dataset

    samples, model, names = None, None, []
    for path in paths:
        try:
            model = load_model(path)
            names.append(f"model {path.name}")
            continue
        except FileFormatError as model_error:
            try:
                samples = load_dataset(path).quaternions
                names.append(f"data {path.name}")
            except FileFormatError as data_error:
                raise ConfigError(
                    f"{path} is neither a model ({model_error.problem}) nor a dataset "
                    f"({data_error.problem})"
                ) from None
    return plot(out, samples=samples, model=model, title=", ".join(names))


@dataclass(frozen=True)
class PlotOptions:
    """``limbctl plot``: the command line's options."""

    inputs: tuple[Path, ...]
    out: Path


def run_plot(options: PlotOptions) -> int:
    """Draw the inputs to the PNG."""
    say(f"wrote {plot_files(list(options.inputs), options.out)}")
    return 0


@dataclass(frozen=True)
class InfoOptions:
    """``limbctl info``: the command line's options (no ``file``: the bus)."""

    file: Path | None = None
    connection: Connection = field(default_factory=Connection)


def run_info(options: InfoOptions) -> int:
    """Print what a file holds, or the servos on the bus and the pose; 3 when one is in alarm."""
    if options.file is not None:
        return _info_file(options.file)
    from limbctl.servo.control_table import Register, model_name

    with open_connection(options.connection) as session:
        bus, rig = session.rig.bus, session.rig
        where = "embedded simulator" if session.simulated else bus.port_name
        print(f"bus: {where} at {bus.baud} bps, fast sync read: {bus.fast_sync_read}")
        errors = bus.read_hardware_errors()
        # read past the alert bit: a servo in alarm is what info is asked about
        torque = bus.sync_read(Register.TORQUE_ENABLE, check_alert=False)
        ticks = bus.sync_read(Register.PRESENT_POSITION, check_alert=False)
        for servo_id in bus.ids:
            print(
                f"servo {servo_id}: {model_name(bus.models[servo_id])}, firmware "
                f"{bus.firmware[servo_id]}, torque {'on' if torque[servo_id] else 'off'}"
                f", position {ticks[servo_id]}, "
                f"hardware errors: {', '.join(errors[servo_id]) or 'none'}"
            )
        pan, tilt = rig.ticks_to_angles(ticks[rig.profile.pan.id], ticks[rig.profile.tilt.id])
        print(f"pose: pan {math.degrees(pan):+.1f} deg, tilt {math.degrees(tilt):+.1f} deg")
    in_alarm = [str(i) for i, bits in errors.items() if bits]
    if in_alarm:
        say(
            f"servo {', '.join(in_alarm)} in alarm: fix the cause, then `limbctl reboot` "
            f"(with the same --port/--rig) clears it"
        )
        return 3
    return 0


def _info_file(path: Path) -> int:
    """Describe a model or dataset file, told apart by its first bytes."""
    from limbctl.envelope import load_header
    from limbctl.envelope.base import is_model_file
    from limbctl.teach.dataset import is_dataset_file, load_dataset

    if is_model_file(path):
        header = load_header(path)
        print(f"{path}: {header['kind']} model, format {header['format_version']}")
        for key, value in {**header["params"], **header["metadata"]}.items():
            print(f"  {key}: {value}")
        return 0
    if not is_dataset_file(path):
        _neither(path)
    data = load_dataset(path)
    print(f"{path}: dataset of {len(data)} samples from rig {data.header.rig!r}")
    print(f"  created {data.header.created}, {data.t[-1] if len(data) else 0:.1f} s recorded")
    calibration = data.header.calibration
    if calibration is None:
        print("  calibration: not recorded (made before limbctl recorded it)")
    else:
        for name in calibration.joint_names:  # pan, tilt (and roll on a three-servo rig)
            joint = getattr(calibration, name)
            print(
                f"  {name}: zero tick {joint.zero_tick}, direction {joint.direction:+d}, "
                f"limits {joint.min_deg:g} .. {joint.max_deg:g} deg"
            )
    if data.dropped_tail:
        print(f"  note: {data.dropped_tail}")
    return 0


def _neither(path: Path) -> None:
    """Refuse a file that begins as neither a model nor a dataset, with both loaders' words."""
    from limbctl.envelope import load_header
    from limbctl.teach.dataset import load_dataset

    problems = []
    for kind, loader in (("a model", load_header), ("a dataset", load_dataset)):
        try:
            loader(path)
        except FileFormatError as exc:
            problems.append(f"as {kind}: {exc.problem}")
    raise FileFormatError(path, f"neither a limbctl model nor a dataset ({'; '.join(problems)})")


@dataclass(frozen=True)
class EvalOptions:
    """``limbctl eval``: the command line's options."""

    out: Path = Path("eval-results")
    quick: bool = False
    jobs: int = 0


def run_evaluation(options: EvalOptions) -> int:
    """Run the papers' experiments; the status of :func:`limbctl.eval.experiments.run_eval`."""
    from limbctl.eval.experiments import run_eval

    return int(run_eval(out=options.out, quick=options.quick, jobs=options.jobs))
