"""wavetrace: a fast, bit-reproducible CPU path tracer, from Python.

Open a scene (TOML, glTF/GLB, PLY), pick a camera and render into NumPy
arrays::

    import wavetrace
    scene = wavetrace.load("model.glb")
    out = scene.render(spp=64, env="studio.hdr", aovs=["depth", "normal"])
    out["color"]   # float32, H x W x 4, linear RGB + alpha
    out["depth"]   # float32, H x W, distance along the camera ray (inf: none)

The images are the command line's, bit for bit, for the same settings
(``wavetrace FILE --spp N --seed S --out x.exr``). A render releases the
GIL, stops with ``KeyboardInterrupt`` on Ctrl-C and reports progress to an
optional callback (or a ``tqdm`` bar). See docs/python.md.
"""

from __future__ import annotations

import warnings as _warnings
from typing import Any, Callable, Dict, Iterable, Iterator, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from . import _wavetrace
from ._wavetrace import Camera, WavetraceError

__all__ = ["Camera", "Scene", "View", "Views", "WavetraceError", "cornell", "load", "views"]

PathLike = Union[str, "os.PathLike[str]"]
Env = Union[str, "os.PathLike[str]", Sequence[float]]


def _env_text(env: Optional[Env]) -> Optional[str]:
    if env is None:
        return None
    if isinstance(env, (str, bytes)) or hasattr(env, "__fspath__"):
        import os

        return os.fsdecode(env)
    colour = [float(c) for c in env]
    if len(colour) != 3:
        raise ValueError(f"env is a file or an (r, g, b) colour: got {len(colour)} numbers")
    return ",".join(repr(c) for c in colour)


class Scene:
    """A scene opened by :func:`load`: its geometry, materials, lights and
    prepared renderer (kept between renders that change only the camera
    or the seed)."""

    def __init__(self, native: Any) -> None:
        self._native = native

    @property
    def name(self) -> str:
        """The scene's name (its file's stem)."""
        return self._native.name

    @property
    def camera(self) -> Camera:
        """The scene's own camera: the file's, or the default framing."""
        return self._native.camera

    @property
    def resolution(self) -> Tuple[int, int]:
        """The scene's own image size ``(width, height)``."""
        return self._native.resolution

    @property
    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """The corners ``(min, max)`` of the box around the geometry."""
        lo, hi = self._native.bounds
        return np.array(lo, dtype=np.float32), np.array(hi, dtype=np.float32)

    @property
    def center(self) -> np.ndarray:
        """The centre of :attr:`bounds`."""
        lo, hi = self.bounds
        return (lo + hi) / 2

    @property
    def triangles(self) -> int:
        """How many triangles the scene holds (each instance counted)."""
        return self._native.triangles

    @property
    def spheres(self) -> int:
        """How many spheres the scene holds."""
        return self._native.spheres

    @property
    def sources(self) -> list:
        """The files the scene was read from."""
        return self._native.sources

    @property
    def objects(self) -> Dict[int, str]:
        """The object-id legend ``{id: name}`` of ``object_id`` images: one
        object per scene-file entry or glTF node, from 1 (0: background)."""
        return dict(self._native.objects)

    @property
    def warnings(self) -> list:
        """What the loader had to say (ignored extensions, skipped lines)."""
        return self._native.warnings

    def render(
        self,
        camera: Optional[Camera] = None,
        *,
        spp: int = 16,
        seed: int = 0,
        width: Optional[int] = None,
        height: Optional[int] = None,
        integrator: Optional[str] = None,
        sampler: Optional[str] = None,
        max_depth: Optional[int] = None,
        engine: Optional[str] = None,
        env: Optional[Env] = None,
        env_strength: Optional[float] = None,
        env_rotation: Optional[float] = None,
        aovs: Iterable[str] = (),
        transparent: bool = False,
        threads: Optional[int] = None,
        progress: Optional[Union[Callable[[int, int], Any], Any]] = None,
    ) -> Dict[str, np.ndarray]:
        """Render the scene and return its images as arrays.

        ``camera`` defaults to the scene's own; ``width``/``height`` to the
        scene's resolution; ``integrator`` (``"nee"``, ``"bsdf"``,
        ``"report"``), ``sampler`` (``"sobol"``, ``"independent"``) and
        ``max_depth`` to the scene's or wavetrace's defaults; ``threads``
        to every core. ``env`` lights the scene by an equirectangular
        ``.exr``/``.hdr`` file or an ``(r, g, b)`` radiance, replacing its
        own environment (``env_strength``, ``env_rotation`` in degrees about
        +Y); ``transparent=True`` hides it from camera rays (black
        background; it still lights the scene). ``aovs`` asks for auxiliary
        images: ``"albedo"``, ``"normal"``, ``"depth"`` (distance along the
        ray), ``"zdepth"`` (along the camera's axis), ``"object_id"``,
        ``"variance"``. ``progress`` is called
        as ``progress(done, total)`` (samples per pixel) between sample
        passes, or, for an object with ``update`` such as a ``tqdm`` bar,
        ``progress.update(n)``.

        Returns ``{"color": H x W x 4 float32 (linear RGB, and alpha: the
        fraction of the pixel's camera rays that hit something), and one
        array per AOV}``: ``depth``/``zdepth`` H x W float32,
        ``object_id`` H x W uint32 (see :attr:`objects`), the others
        H x W x 3 float32; row 0 is the image's top. The arrays are read-only views of the render's
        memory (no copy); ``.copy()`` one to write into it.
        """
        native = self._native.render(
            camera,
            spp=spp,
            seed=seed,
            width=width,
            height=height,
            integrator=integrator,
            sampler=sampler,
            max_depth=max_depth,
            engine=engine,
            env=_env_text(env),
            env_strength=env_strength,
            env_rotation=env_rotation,
            aovs=list(aovs),
            transparent=transparent,
            threads=threads,
            progress=progress,
        )
        return {name: np.asarray(buffer) for name, buffer in native.items()}

    def __repr__(self) -> str:
        return repr(self._native)


def load(path: PathLike, camera: Optional[Union[str, int]] = None) -> Scene:
    """Open a scene file: a TOML scene, a glTF/GLB asset or a PLY mesh.

    ``camera`` picks one of a glTF file's cameras by name or index (the
    first by default; without any, the asset is framed from the front,
    right and above). Errors (a missing file, a bad field, a hostile
    asset) raise :class:`WavetraceError` with the command line's message.
    """
    return Scene(_wavetrace.load(path, None if camera is None else str(camera)))


def cornell() -> Scene:
    """The built-in Cornell box, ``wavetrace``'s default scene."""
    return Scene(_wavetrace.cornell())


class View(NamedTuple):
    """One view of a views job (see :func:`views`)."""

    asset: str
    """The asset's name (its output folder's in ``wavetrace views``)."""
    view: int
    """The view's index among the asset's views."""
    arrays: Dict[str, np.ndarray]
    """``color`` (H x W x 4 float32: linear RGB, denoised when the job
    denoises, and alpha, 1 unless the job asks for ``alpha``) and one array
    per AOV the job asks for: ``depth``/``zdepth`` (H x W, in the job's
    world units), ``normal`` (world or camera axes, as the job says),
    ``albedo``, ``variance`` (H x W x 3), ``object_id`` (H x W uint32)."""
    camera: Camera
    """The view's camera in the job's world (``transforms.json``'s)."""
    objects: Dict[int, str]
    """The asset's object-id legend ``{id: name}``."""
    file: str
    """The asset's file."""


class Views:
    """The views of a job as they are rendered: an iterator of :class:`View`.

    Rendering runs on a thread of its own, at most one view ahead of the
    consumer, with the GIL released; Ctrl-C stops it with
    ``KeyboardInterrupt``; :meth:`close` (or dropping the iterator) stops
    the job. Assets that cannot be loaded are skipped with a warning and
    listed in :attr:`failed`."""

    def __init__(self, native: Any, progress: Optional[Any]) -> None:
        self._native = native
        self._progress = progress
        self._done = 0
        self._ended = False

    def __iter__(self) -> "Views":
        return self

    def __next__(self) -> View:
        try:
            item = next(self._native)
        except StopIteration:
            if not self._ended:
                self._ended = True
                for file, why in self.failed:
                    _warnings.warn(f"wavetrace.views: skipped {file}: {why}", RuntimeWarning, stacklevel=2)
            raise
        asset, file, view, buffers, camera, objects = item
        arrays = {name: np.asarray(buffer) for name, buffer in buffers}
        self._done += 1
        if self._progress is not None:
            if hasattr(self._progress, "update") and not callable(self._progress):
                self._progress.update(1)
            else:
                self._progress(self._done, self.total)
        return View(asset, view, arrays, camera, dict(objects), str(file))

    @property
    def total(self) -> int:
        """How many views this run renders (its shard's share)."""
        return self._native.total

    @property
    def failed(self) -> list:
        """``(asset file, error)`` for each asset that could not be rendered
        (complete once the iteration has ended)."""
        return self._native.failed

    def close(self) -> None:
        """Stop the job now."""
        self._native.close()

    def __enter__(self) -> "Views":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def views(
    job: PathLike,
    *,
    threads: Optional[int] = None,
    shard: Optional[Tuple[int, int]] = None,
    engine: Optional[str] = None,
    progress: Optional[Union[Callable[[int, int], Any], Any]] = None,
) -> Views:
    """Render a ``wavetrace views`` job file (docs/views.md) in memory,
    yielding each view as a :class:`View` ``(asset, view, arrays, camera,
    objects, file)``: every asset loaded and built once for all its views,
    views in order, the same bits as the command line's files for the same
    job, and no file written. ``shard=(i, n)`` renders the command line's
    ``--shard i/n`` share; ``threads`` defaults to every core;
    ``progress`` is called as ``progress(done, total)`` after each view
    (or ``progress.update(1)`` on a ``tqdm`` bar)::

        for v in wavetrace.views("job.toml", threads=8):
            batch.append((v.arrays["color"], v.camera.matrix()))
    """
    import os

    native = _wavetrace.views(os.fspath(job), threads=threads, shard=shard, engine=engine)
    return Views(native, progress)
