"""Cameras over the cutting table: one small interface, a real and a synthetic one.

``Camera.read()`` returns one BGR uint8 frame; ``close()`` releases the device; cameras
are context managers and know their ``resolution`` (width, height). Averaging several
frames cuts sensor noise by sqrt(n) for a still table, which helps the sub-pixel
lattice fit more than any filter would.
"""

from __future__ import annotations

import abc
import logging
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

__all__ = ["Camera", "CameraError", "SimulatedCamera", "VideoCaptureCamera", "open_camera"]

log = logging.getLogger(__name__)


class CameraError(RuntimeError):
    """The camera could not be opened or stopped delivering frames."""


class Camera(abc.ABC):
    """A source of BGR uint8 frames of the table."""

    average: int = 1

    @property
    @abc.abstractmethod
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""

    @abc.abstractmethod
    def _read_one(self) -> np.ndarray:
        """One raw frame (H, W, 3) uint8."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the device (idempotent)."""

    def read(self) -> np.ndarray:
        """The mean of ``average`` consecutive frames, (H, W, 3) BGR uint8."""
        n = max(1, int(self.average))
        first = self._read_one()
        if n == 1:
            return first
        acc = first.astype(np.float32)
        for _ in range(n - 1):
            acc += self._read_one()
        return np.clip(np.rint(acc / n), 0, 255).astype(np.uint8)

    def __enter__(self) -> Camera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _is_gstreamer(source: str) -> bool:
    return "!" in source


class VideoCaptureCamera(Camera):
    """Any OpenCV ``VideoCapture`` source: a device index, a video file or a GStreamer
    pipeline (a string containing ``!``).

    Parameters
    ----------
    source : int or str
    resolution : (width, height), optional
        Requested capture size; the driver may pick the nearest it supports, and
        ``resolution`` reports what it actually delivers.
    exposure : float, optional
        Manual exposure in the driver's units (V4L2: 100 µs steps); auto otherwise.
    average : int
        Frames averaged per :meth:`read`.
    warmup : int
        Frames dropped after opening (auto-exposure and white balance settle).
    """

    def __init__(self, source: int | str, *, resolution: tuple[int, int] | None = None,
                 exposure: float | None = None, average: int = 1, warmup: int = 0,
                 api: int | None = None) -> None:
        if average < 1:
            raise ValueError(f"average must be at least 1 frame, got {average}")
        self.source = source
        self.average = int(average)
        if api is None:
            api = cv2.CAP_GSTREAMER if isinstance(source, str) and _is_gstreamer(source) \
                else cv2.CAP_ANY
        self._cap = cv2.VideoCapture(source, api)
        if not self._cap.isOpened():
            raise CameraError(f"camera {source!r}: cannot open (no such device or file, "
                              "or OpenCV lacks the backend)")
        if resolution is not None:
            self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, float(resolution[0]))
            self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, float(resolution[1]))
        if exposure is not None:
            # V4L2 convention: 0.25 selects manual exposure, 0.75 automatic.
            self._cap.set(cv2.CAP_PROP_AUTO_EXPOSURE, 0.25)
            if not self._cap.set(cv2.CAP_PROP_EXPOSURE, float(exposure)):
                log.warning("camera %r: the driver refused exposure %s", source, exposure)
        for _ in range(max(0, warmup)):
            self._cap.grab()
        w = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        h = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        self._resolution = (w, h)

    @property
    def resolution(self) -> tuple[int, int]:
        return self._resolution

    def _read_one(self) -> np.ndarray:
        if self._cap is None:
            raise CameraError(f"camera {self.source!r} is closed")
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise CameraError(f"camera {self.source!r}: no frame (end of file or device "
                              "disconnected)")
        if frame.ndim == 2:
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        return frame

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


class SimulatedCamera(Camera):
    """The synthetic camera of :mod:`simulators.camera` behind the same interface.

    ``truth`` exposes the simulator's ground truth of the last frame (for tests and
    benchmarks); the station itself never reads it.
    """

    def __init__(self, sim: Any, *, average: int = 1) -> None:
        if average < 1:
            raise ValueError(f"average must be at least 1 frame, got {average}")
        self.sim = sim
        self.average = int(average)

    @property
    def resolution(self) -> tuple[int, int]:
        return tuple(self.sim.resolution)

    @property
    def truth(self) -> Any:
        return self.sim.truth

    def _read_one(self) -> np.ndarray:
        try:
            return self.sim.read()
        except RuntimeError as exc:
            raise CameraError(f"synthetic camera: {exc}") from None

    def close(self) -> None:
        self.sim.close()


def open_camera(source: int | str | None = None, *, simulate: bool = False,
                sim_factory: Callable[[], Any] | None = None, **kw: Any) -> Camera:
    """The station's camera: ``VideoCaptureCamera(source)`` or, with ``simulate``, the
    synthetic camera built by ``sim_factory`` (the caller's: vision never imports the
    simulators).

    A ``source`` string of digits is a device index (as typed on a command line).
    """
    average = int(kw.pop("average", 1))
    if simulate:
        if sim_factory is None:
            raise ValueError("a simulated camera needs sim_factory (e.g. "
                             "station.simstation.simulated_camera)")
        return SimulatedCamera(sim_factory(), average=average)
    if source is None:
        raise ValueError("no camera source given (device index, video file or GStreamer "
                         "pipeline); use --simulate for the synthetic camera")
    if isinstance(source, str) and source.isdigit():
        source = int(source)
    return VideoCaptureCamera(source, average=average, **kw)
