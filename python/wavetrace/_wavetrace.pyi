"""Type stubs of wavetrace's native module."""

from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

Matrix4 = Sequence[Sequence[float]]
Matrix3 = Sequence[Sequence[float]]
Vec3 = Sequence[float]

class WavetraceError(Exception):
    """A scene, setting or file wavetrace refuses; the command line's message."""

class Camera:
    """A pinhole camera: a field of view (any image size), or OpenCV intrinsics (fx, fy, cx, cy; no skew)."""

    @staticmethod
    def look_at(eye: Vec3, target: Vec3, up: Vec3 = ..., fov_y: float = 40.0) -> Camera: ...
    @staticmethod
    def from_matrix(matrix: Matrix4, fov_y: float = 40.0) -> Camera:
        """From a camera-to-world matrix, OpenGL/NeRF convention (looks down -Z, +Y up)."""
    @staticmethod
    def from_opencv(k: Matrix3, r: Matrix3, t: Vec3, width: int, height: int) -> Camera:
        """From OpenCV's K, R, t (x right, y down, z forward; pixel centres at integers); any fx, fy, cx, cy."""
    @property
    def position(self) -> Tuple[float, float, float]: ...
    @property
    def forward(self) -> Tuple[float, float, float]: ...
    @property
    def up(self) -> Tuple[float, float, float]: ...
    @property
    def fov_y(self) -> float: ...
    def matrix(self) -> List[List[float]]:
        """The 4x4 camera-to-world matrix, OpenGL convention."""
    def intrinsics(self, width: int, height: int) -> List[List[float]]:
        """OpenCV's K for a width x height image."""
    def extrinsics(self) -> Tuple[List[List[float]], List[float]]:
        """OpenCV's (R, t), world to camera."""
    def project(self, point: Vec3, width: int, height: int) -> Optional[Tuple[float, float]]:
        """Continuous pixel coordinates of a world point (pixel (i, j) covers [i, i+1) x [j, j+1)), None behind."""

class Buffer:
    __array_interface__: Dict[str, Any]

class Scene:
    name: str
    camera: Camera
    resolution: Tuple[int, int]
    bounds: Tuple[Tuple[float, float, float], Tuple[float, float, float]]
    triangles: int
    spheres: int
    sources: List[str]
    warnings: List[str]
    objects: List[Tuple[int, str]]
    def render(
        self,
        camera: Optional[Camera] = None,
        spp: int = 16,
        seed: int = 0,
        width: Optional[int] = None,
        height: Optional[int] = None,
        integrator: Optional[str] = None,
        sampler: Optional[str] = None,
        max_depth: Optional[int] = None,
        engine: Optional[str] = None,
        env: Optional[str] = None,
        env_strength: Optional[float] = None,
        env_rotation: Optional[float] = None,
        aovs: List[str] = ...,
        transparent: bool = False,
        threads: Optional[int] = None,
        progress: Optional[Callable[..., Any]] = None,
    ) -> Dict[str, Buffer]: ...

def load(path: Any, camera: Optional[str] = None) -> Scene: ...
def cornell() -> Scene: ...

class Views:
    """A views job rendering in memory (wavetrace.views wraps it)."""

    def __iter__(self) -> Views: ...
    def __next__(self) -> Tuple[str, str, int, List[Tuple[str, Buffer]], Camera, List[Tuple[int, str]]]: ...
    @property
    def total(self) -> int: ...
    @property
    def failed(self) -> List[Tuple[str, str]]: ...
    def close(self) -> None: ...

def views(job: str, threads: Optional[int] = None, shard: Optional[Tuple[int, int]] = None, engine: Optional[str] = None) -> Views:
    """Start a views job in memory."""
