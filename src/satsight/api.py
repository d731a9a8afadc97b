"""The Python interface: scenarios in, frames (arrays and labels) or datasets out.

Every name here is also ``satsight.NAME`` (imported on first use, so that ``import
satsight`` stays cheap)::

    import satsight

    scenario = satsight.load_scenario("scenario.yaml", overrides={"camera.width_px": 512})
    for frame in satsight.render_frames(scenario, indices=[0, 3]):
        frame.dn, frame.object_mask, frame.depth_m, frame.labels    # arrays, JSON labels

    dataset = satsight.generate(scenario, "out/ds")                # same as satsight generate
    for frame in dataset:
        frame.labels, frame.dn(), frame.object_mask()                # files read on demand
    satsight.export_dataset(dataset, "out/ds_bop", "bop")

The module sits beside the command line: it wires the stages below it (``config``,
``pipeline``, ``generation``, ``dataset``) and nothing below imports it. The renderer
(Mitsuba, Dr.Jit) is imported only when a frame is rendered.

Arrays follow the dataset's conventions (docs/conventions.md): (H, W) images with pixel
(0, 0) the centre of the top-left pixel, OpenCV camera frame, SI units,
``x_cam = R(q_cam_from_body) @ x_body + t_cam_from_body_m`` with scalar-first quaternions.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from satsight.config.overrides import override_scenario
from satsight.config.scenario import Scenario, parse_scenario
from satsight.config.scenario import load_scenario as load_scenario_file
from satsight.dataset import reader
from satsight.errors import SatsightError

if TYPE_CHECKING:
    from satsight.dataset.export import ExportSummary
    from satsight.dataset.export.source import ExportFrame
    from satsight.dataset.frame_files import FrameArrays
    from satsight.pipeline import FrameEngine
    from satsight.scene.mesh import TargetMesh

#: What names a scenario: a YAML file's path, the scenario as a mapping (the YAML's keys),
#: or a ``Scenario`` already validated.
ScenarioSource = str | os.PathLike | Mapping[str, Any] | Scenario


def load_scenario(source: ScenarioSource, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """A validated scenario from a YAML file, a mapping or a ``Scenario``, with optional
    dotted-key ``overrides`` (see ``override``).

    A YAML file's relative paths (mesh, TLE, OEM files) are resolved against its folder, a
    mapping's against the current folder. A bad key or value is a SatsightError naming it
    (``camera.width_px: Input should be greater than or equal to 1``).
    """
    if isinstance(source, Scenario):
        scenario = source
    elif isinstance(source, Mapping):
        scenario = parse_scenario(dict(source), "scenario mapping")
    elif isinstance(source, str | os.PathLike):
        scenario = load_scenario_file(source)
    else:
        raise SatsightError(
            "a scenario is a YAML file's path, a mapping of its keys or a satsight.Scenario; "
            f"got {type(source).__name__}"
        )
    return scenario if not overrides else override(scenario, overrides)


def override(scenario: Scenario, overrides: Mapping[str, Any]) -> Scenario:
    """A copy of ``scenario`` with values replaced by dotted key, validated again.

    overrides: ``{"camera.width_px": 512, "sampler.frame_count": 20,
    "frames.0.distance_km": 2.5, "outputs.crop.size_px": 64}``: keys as the validation
    messages name them (integers index lists); a mapping value replaces a whole section;
    an absent section is created. Unknown keys and bad values are a SatsightError naming
    the key.
    """
    return override_scenario(scenario, overrides)


class _PoseLabels:
    """The pose and intrinsics of a frame, as arrays, from its ``labels``."""

    labels: dict

    @property
    def index(self) -> int:
        """The frame's index in the dataset (0-based)."""
        return int(self.labels["frame_index"])

    @property
    def q_cam_from_body(self) -> np.ndarray:
        """(4,) float64 rotation from the target's body frame to the camera frame, scalar
        first [qw, qx, qy, qz], Hamilton, qw >= 0."""
        return np.asarray(self.labels["q_cam_from_body"], dtype=np.float64)

    @property
    def t_cam_from_body_m(self) -> np.ndarray:
        """(3,) float64 position of the body frame's origin in the camera frame, m."""
        return np.asarray(self.labels["t_cam_from_body_m"], dtype=np.float64)

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float64 intrinsic matrix of the full frame, pixels."""
        return np.asarray(self.labels["K"], dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Frame(_PoseLabels):
    """One rendered frame, held in memory: its images and its labels.

    labels: the frame's label record, exactly as a dataset of the same scenario stores it
    in ``labels.json`` less the files (``files``, ``checksums``, a crop's ``files``); see
    docs/dataset_format.md. crop_xyxy_px: the crop window (x0, y0, x1, y1), exclusive
    ends, when the scenario asks for ``outputs.crop``; None otherwise. arrays: the render's
    and the detector's outputs, which the properties below give.
    """

    labels: dict
    arrays: FrameArrays
    crop_xyxy_px: tuple[int, int, int, int] | None = None

    @property
    def dn(self) -> np.ndarray:
        """(H, W) uint16 digital numbers read out by the detector (bias included)."""
        return self.arrays.dn_image.dn

    @property
    def radiance_w_m2_sr(self) -> np.ndarray:
        """(H, W, 3) float32 in-band radiance towards the camera, W m^-2 sr^-1 (R, G, B)."""
        return self.arrays.image.radiance_w_m2_sr

    @property
    def depth_m(self) -> np.ndarray:
        """(H, W) float32 depth along +z_cam of the surface at each pixel centre, m; 0
        where the ray misses the target."""
        return self.arrays.image.depth_m

    @property
    def part_id(self) -> np.ndarray:
        """(H, W) uint16 part index + 1 of the surface seen, 0 for background."""
        return self.arrays.image.part_id

    @property
    def object_mask(self) -> np.ndarray:
        """(H, W) bool: True where the ray through the pixel centre hits the target (a copy
        of the frame's own mask, which is read-only)."""
        return self.arrays.image.object_mask.copy()

    @property
    def normals_cam(self) -> np.ndarray:
        """(H, W, 3) float32 unit surface normals in the camera frame, zero for
        background."""
        return self.arrays.image.normals_cam

    @property
    def background_mask(self) -> np.ndarray:
        """(H, W) uint8 body behind the target: 0 space (or the target), 1 the Earth,
        2 the Moon."""
        return self.arrays.image.background_mask()


class Simulator:
    """A scenario ready to render: the mesh, frame plan, sensor and compiled renderer,
    built once and kept, so that frames after the first cost only their own rendering.

    scenario: anything ``load_scenario`` takes; overrides: dotted keys (see ``override``).
    Frames are those ``satsight generate`` writes, numbered the same way, and identical
    to them (each frame's random numbers come from the scenario seed and its index).
    """

    def __init__(self, scenario: ScenarioSource, overrides: Mapping[str, Any] | None = None):
        from satsight.pipeline import FrameEngine

        self.scenario: Scenario = load_scenario(scenario, overrides)
        self._engine = FrameEngine(self.scenario, normals=True)
        self._engine.load_star_catalogue()  # a missing catalogue fails here, not mid-loop

    @property
    def engine(self) -> FrameEngine:
        """The pipeline's frame engine (``satsight.pipeline.FrameEngine``)."""
        return self._engine

    @property
    def mesh(self) -> TargetMesh:
        """The target mesh, in its body frame (metres)."""
        return self._engine.mesh

    @property
    def frame_count(self) -> int:
        """Frames the scenario makes (the planned frames that pass the visibility rule)."""
        return self._engine.frame_count

    def __len__(self) -> int:
        return self.frame_count

    def header(self) -> dict:
        """The dataset description of the scenario: what ``labels.json`` holds besides
        its frames (camera, sensor, target, conventions)."""
        return self._engine.header()

    def _check_index(self, index: int) -> int:
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise SatsightError(f"a frame index is an integer, got {index!r}")
        if not 0 <= index < self.frame_count:
            raise SatsightError(
                f"frame {index} is not among the scenario's {self.frame_count} frames "
                f"(0 to {self.frame_count - 1})"
            )
        return int(index)

    def render(self, index: int) -> Frame:
        """Render frame ``index`` through labels, optics and detector; nothing is written."""
        from satsight.dataset.journal import record_line

        engine = self._engine
        record, arrays, box = engine.finish(engine.render(self._check_index(index)))
        # The record as the dataset's journal stores it: plain JSON values.
        return Frame(json.loads(record_line(record)), arrays, box)

    def frames(self, indices: Iterable[int] | None = None) -> Iterator[Frame]:
        """The frames ``indices`` (default: all, in order), rendered one at a time as the
        iterator is advanced; every index is checked before the first is rendered."""
        chosen = range(self.frame_count) if indices is None else list(indices)
        for index in chosen:
            self._check_index(index)
        return (self.render(index) for index in chosen)


def render_frames(
    scenario: ScenarioSource,
    indices: Iterable[int] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> Iterator[Frame]:
    """Render the frames ``indices`` of a scenario (default: all) to arrays, lazily: each
    frame is rendered when the iterator reaches it. Shorthand for
    ``Simulator(scenario, overrides).frames(indices)``."""
    return Simulator(scenario, overrides).frames(indices)


def generate(
    scenario: ScenarioSource,
    out_dir: str | os.PathLike,
    *,
    overwrite: bool = False,
    resume: bool = False,
    shard: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    on_frame_done: Callable[[int, int], None] | None = None,
    render_processes: int | str = 1,
) -> Dataset:
    """Render a scenario into the dataset folder ``out_dir``, as ``satsight generate``
    does, and return the opened dataset.

    overwrite: replace a dataset already in the folder. resume: finish the interrupted
    dataset of the same scenario in it (a complete one is returned as it is). shard:
    ``"K/N"``, render only shard K of N. workers / scheduler: render on a local Dask
    cluster of that many processes, or on the Dask scheduler at that address.
    on_frame_done(done, total): called after each committed frame, one call at a time, on
    the thread that commits frames (not always the caller's). render_processes: render in
    that many local processes, or ``"auto"`` as ``satsight generate`` does (several for
    long runs of small frames, which they make faster); processes are spawned, so the
    calling script needs Python's ``if __name__ == "__main__":`` guard.

    Frames are committed one at a time, so a run that fails or is stopped keeps its
    committed frames and never leaves a half-written one; ``resume=True`` finishes it.
    The first Ctrl-C finishes the frames in flight, then raises KeyboardInterrupt.
    """
    from satsight.run.generation import generate_dataset
    from satsight.run.interrupt import StopFlag, stop_on_sigint
    from satsight.run.shard import Shard

    if overwrite and resume:
        raise SatsightError("give overwrite=True or resume=True, not both")
    scenario = load_scenario(scenario, overrides)
    out_dir = Path(out_dir)
    stop = StopFlag()
    with stop_on_sigint(stop):
        summary = generate_dataset(
            scenario,
            out_dir,
            overwrite=overwrite,
            resume=resume,
            shard=None if shard is None else Shard.parse(shard),
            workers=workers,
            scheduler=scheduler,
            on_frame_done=on_frame_done,
            stop=stop,
            render_processes=render_processes,
        )
    if summary.interrupted:
        raise KeyboardInterrupt(
            f"stopped: {summary.committed_before + summary.rendered} of {summary.frame_count} "
            f"frames committed in {out_dir}; finish with generate(..., resume=True)"
        )
    return open_dataset(out_dir)


#: The ``DatasetFrame`` method that reads each file key (for error messages).
_READER_OF_KEY = {
    "dn_png16": "dn",
    "preview_png8": "preview",
    "part_mask_png16": "part_id",
    "background_mask_png": "background_mask",
    "radiance_exr": "radiance_w_m2_sr",
    "normals_exr": "normals_cam",
}


@dataclass(frozen=True)
class DatasetFrame(_PoseLabels):
    """One frame of a dataset folder: its labels, and its images read from its files on
    demand. ``crop=True`` reads the frame's crop instead (``outputs.crop``).

    labels: the frame's record in ``labels.json`` (docs/dataset_format.md).
    """

    dataset: reader.Dataset
    labels: dict

    def path(self, key: str, crop: bool = False) -> Path | None:
        """Absolute path of one of the frame's files (file keys ``dn_png16``,
        ``object_mask_png``, ``depth_exr``, ...; docs/dataset_format.md); None if not
        written."""
        return self.dataset.path(self.labels, key, crop)

    def _view(self, crop: bool) -> ExportFrame:
        from satsight.dataset.export.source import export_frame

        if crop and not self.labels.get("crop"):
            raise SatsightError(
                f"frame {self.index} has no crop; generate with outputs.crop (e.g. "
                "overrides={'outputs.crop.size_px': 256}) or read the full frame"
            )
        return export_frame(self.dataset, self.labels, crop)

    def _file(self, key: str, crop: bool) -> Path:
        from satsight.dataset.export.source import require_file

        return require_file(self._view(crop), key, f"DatasetFrame.{_READER_OF_KEY[key]}()")

    def _png(self, key: str, crop: bool) -> np.ndarray:
        from satsight.dataset.image_files import read_png

        return read_png(self._file(key, crop))

    def _exr(self, key: str, crop: bool) -> dict[str, np.ndarray]:
        from satsight.dataset.image_files import read_exr

        return read_exr(self._file(key, crop))

    def dn(self, crop: bool = False) -> np.ndarray:
        """(H, W) uint16 digital numbers read out by the detector (bias included)."""
        return self._png("dn_png16", crop)

    def object_mask(self, crop: bool = False) -> np.ndarray:
        """(H, W) bool: True where the ray through the pixel centre hits the target."""
        from satsight.dataset.export.source import read_mask

        return read_mask(self._view(crop), "DatasetFrame.object_mask()")

    def part_id(self, crop: bool = False) -> np.ndarray:
        """(H, W) uint16 part index + 1 of the surface seen, 0 for background."""
        return self._png("part_mask_png16", crop)

    def background_mask(self, crop: bool = False) -> np.ndarray:
        """(H, W) uint8 body behind the target: 0 space (or the target), 1 Earth, 2 Moon."""
        return self._png("background_mask_png", crop)

    def preview(self, crop: bool = False) -> np.ndarray:
        """(H, W) uint8 display stretch of the DN (for looking, not for measuring)."""
        return self._png("preview_png8", crop)

    def depth_m(self, crop: bool = False) -> np.ndarray:
        """(H, W) float32 depth along +z_cam, m; 0 where no surface."""
        from satsight.dataset.export.source import read_depth_m

        return read_depth_m(self._view(crop), "DatasetFrame.depth_m()").astype(np.float32)

    def radiance_w_m2_sr(self, crop: bool = False) -> np.ndarray:
        """(H, W, 3) float32 in-band radiance towards the camera, W m^-2 sr^-1 (R, G, B)."""
        return self._exr("radiance_exr", crop)["RGB"]

    def normals_cam(self, crop: bool = False) -> np.ndarray:
        """(H, W, 3) float32 unit surface normals in the camera frame, zero for
        background."""
        channels = self._exr("normals_exr", crop)
        return np.stack([channels["X"], channels["Y"], channels["Z"]], axis=-1)


class Dataset(Sequence[DatasetFrame]):
    """An opened dataset folder: a sequence of its frames in frame order (index it, or
    iterate over it: records are read from the journal one at a time).

    root: the folder. header: the dataset description (labels.json without its frames).
    complete: whether every planned frame is committed. reader: the underlying
    ``satsight.dataset.reader.Dataset``.
    """

    def __init__(self, opened: reader.Dataset):
        self.reader = opened

    @property
    def root(self) -> Path:
        return self.reader.root

    @property
    def header(self) -> dict:
        return self.reader.header

    @property
    def complete(self) -> bool:
        return self.reader.complete

    def __len__(self) -> int:
        """Frames committed (all of them in a complete dataset)."""
        return len(self.reader.frames)

    def __getitem__(self, position):
        """The frame at ``position`` (a list of frames for a slice)."""
        if isinstance(position, slice):
            return [DatasetFrame(self.reader, record) for record in self.reader.frames[position]]
        return DatasetFrame(self.reader, self.reader.frames[position])

    def __iter__(self) -> Iterator[DatasetFrame]:
        for record in self.reader.frames:
            yield DatasetFrame(self.reader, record)

    def __repr__(self) -> str:
        state = "complete" if self.complete else "incomplete"
        return f"satsight.Dataset({str(self.root)!r}, {len(self)} frames, {state})"


def open_dataset(root: str | os.PathLike, require_complete: bool = True) -> Dataset:
    """Open the dataset folder ``root``. With ``require_complete=False`` an interrupted
    dataset is opened too (its committed frames); otherwise that is a SatsightError."""
    return Dataset(reader.open_dataset(Path(root), require_complete))


def export_dataset(
    dataset: Dataset | str | os.PathLike,
    out_dir: str | os.PathLike,
    format: str = "bop",
    *,
    split: Sequence[float] = (0.8, 0.1, 0.1),
    seed: int = 0,
    crop: bool = False,
    overwrite: bool = False,
    **options: Any,
) -> ExportSummary:
    """Export a complete dataset to ``out_dir`` in ``format`` (``bop`` or ``speedplus``),
    as ``satsight export`` does: a seeded train / val / test split of ``split`` fractions,
    written whole or not at all.

    crop: export the crops around the target. overwrite: replace an earlier export.
    options: further keywords of ``satsight.dataset.export.export_dataset`` (``domain``
    for SPEED+, ...).
    """
    from satsight.dataset.export import export_dataset as export
    from satsight.dataset.export.splits import SplitRule

    source = dataset.root if isinstance(dataset, Dataset) else Path(dataset)
    fractions = tuple(float(value) for value in split)
    return export(
        source=source,
        out_dir=Path(out_dir),
        fmt=format,
        rule=SplitRule(fractions, seed),
        crop=crop,
        overwrite=overwrite,
        **options,
    )
