"""microsim: a microsurface ray-tracing oracle for Smith-GGX microfacet models, from numpy (docs/guide/python.md).

Type stub of the compiled module (src/python/*.cpp) for editors and type checkers."""
import os
from typing import Any, Callable, Dict, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

Alpha = Union[float, Tuple[float, float], Sequence[float]]
Directions = npt.ArrayLike  # (N, 3) or (3,) unit directions, z-up
Progress = Optional[Callable[[str, int, int], Any]]  # progress(stage, done, total)

__version__: str

class ValidationResult:
    """The report of one validation (what `microsim validate --json` writes)."""
    @property
    def passed(self) -> bool: ...
    @property
    def verdict(self) -> str: ...  # 'pass' or 'fail'
    @property
    def p_value(self) -> float: ...  # Sidak-adjusted smallest p of the statistical tests
    @property
    def statistic(self) -> float: ...
    @property
    def dof(self) -> int: ...
    @property
    def samples(self) -> int: ...
    @property
    def failures(self) -> list[str]: ...
    @property
    def seconds(self) -> float: ...
    @property
    def p_values(self) -> dict[str, float]: ...  # 'chi2_sphere', 'chi2_lobe', statistical checks
    @property
    def worst_cells(self) -> list[dict[str, Any]]: ...
    def to_dict(self) -> dict[str, Any]: ...
    def __bool__(self) -> bool: ...

def validate(samples: Union[np.ndarray, str, os.PathLike], alpha: Alpha, theta: float, phi: float = 0.0,
             pdf: str = "vndf", weights: Optional[np.ndarray] = None, pdfs: Optional[np.ndarray] = None, *,
             bsdf: Optional[str] = None, transport: Optional[str] = None, masking: Optional[str] = None,
             sampling: Optional[str] = None, columns: Optional[str] = None, frame: str = "z-up", rows: int = 31,
             significance: float = 0.01, above_horizon: bool = False, dropped: Optional[int] = None,
             lost_as_zero_weight: bool = False, against: Optional[str] = None, oracle_rays: int = 4000000, seed: int = 1,
             progress: Progress = None) -> ValidationResult:
    """Validates samples (N, 3) float32/float64 against the density they claim (`microsim validate --from`);
    pdfs (N,): the returned pdfs; weights (N,) or (N, C) with bsdf ('mirror', 'conductor:ETA,K', 'dielectric:ETA'):
    the weights; pdf='bsdf' with bsdf: the BSDF's sampling density (`--pdf bsdf`). samples may be the path of a
    sample file (.npy in C or Fortran order, or text) with its columns named as --columns names them."""

def validate_sampler(name: str, alpha: Alpha, theta: float, phi: float = 0.0, *, samples: int = 1000000,
                     seed: int = 1, precision: str = "double", rows: int = 31, significance: float = 0.01,
                     progress: Progress = None) -> ValidationResult:
    """Validates a sampler of the zoo (`microsim validate --sampler`): identical results for the same seed."""

def sample(name: str, wi: Directions, alpha: Alpha, u: npt.ArrayLike,
           precision: str = "double") -> Tuple[np.ndarray, np.ndarray]:
    """Draws with a sampler of the zoo for each row of u (N, 2): (directions (N, 3), pdfs (N,)); NaN rows: no sample."""

def sampler_names() -> list[str]: ...

def validate_all(*, samples: int = 200000, seed: int = 1, precision: str = "double", rows: int = 31,
                 significance: float = 0.01, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """`microsim validate --all`: the dict its --json writes (verdict, summary, results), plus exit_code."""

def albedo_table(*, model: str = "analytic", ndf: str = "ggx", material: str = "mirror", inside: bool = False,
                 alphas: Optional[Sequence[float]] = None, mus: int = 16, tolerance: float = 1e-8,
                 paths: int = 1000000, seed: int = 1, max_order: int = 100, resolution: int = 512,
                 walk_kernel: str = "scalar", threads: int = 0, layout: Optional[str] = None,
                 progress: Progress = None) -> dict[str, Any]:
    """`microsim albedo` (`--layout L` when layout is given, a glass layout too; walk_kernel: `--walk-kernel`):
    the dict its --json writes."""

def anisotropic_albedo_table(*, alphas_x: Sequence[float], alphas_y: Sequence[float], mus: int = 16, phis: int = 8,
                             tolerance: float = 1e-8, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """`microsim albedo --model analytic --alphas AX,... --alphas-y AY,...`: the dict its --json writes."""

def grade_albedo_table(path: Union[str, "os.PathLike[str]"], *, layout: str, ndf: str = "ggx", tolerance: float = 1e-4,
                       table_samples: Optional[int] = None, threads: int = 0,
                       progress: Progress = None) -> dict[str, Any]:
    """`microsim albedo --grade PATH --layout L`: the dict its --json writes, plus exit_code (0 pass, 1 fail)."""

def stability(*, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """`microsim stability`: the dict its --json writes (violations: rows over their bound)."""

def D(m: Directions, alpha: Alpha) -> np.ndarray:
    """GGX normal distribution D(m) (Walter et al. 2007, eq. 33)."""
def Lambda(w: Directions, alpha: Alpha) -> np.ndarray:
    """Smith Lambda(w) (Heitz 2014, eq. 86)."""
def G1(w: Directions, alpha: Alpha) -> np.ndarray:
    """Smith masking G1(w) = 1 / (1 + Lambda(w))."""
def G2(wi: Directions, wo: Directions, alpha: Alpha) -> np.ndarray:
    """Height-correlated masking-shadowing (Heitz 2014, eq. 99)."""
def D_v(wi: Directions, m: Directions, alpha: Alpha) -> np.ndarray:
    """Visible normal distribution D_v(wi, m) (Heitz 2014, eq. 16)."""
def reflection_pdf(wi: Directions, wo: Directions, alpha: Alpha) -> np.ndarray:
    """pdf of the reflected direction under VNDF sampling, D_v / (4 <wi, m>)."""
def mirror_brdf(wi: Directions, wo: Directions, alpha: Alpha) -> np.ndarray: ...
def conductor_brdf(wi: Directions, wo: Directions, alpha: Alpha, eta: complex) -> np.ndarray: ...
def dielectric_bsdf(wi: Directions, wo: Directions, alpha: Alpha, eta: float) -> np.ndarray: ...

def trace_vndf(alpha: Alpha, theta: float, phi: float = 0.0, *, rays: int = 1000000, seed: int = 1, rows: int = 31,
               mesh_level: int = -1, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """Traces the GGX ellipsoid (`microsim trace vndf`): {'rays', 'hits', 'partial', 'attributes', 'binnings':
    {'sphere'|'lobe': {'counts', 'expected_probability', 'solid_angle', 'centres', 'param_theta_deg',
    'param_phi_deg'}}}. Ctrl-C raises KeyboardInterrupt with .partial_result."""

def trace_surface_vndf(surface: "Heightfield", theta: float, phi: float = 0.0, *, rays: int = 1000000, seed: int = 1,
                       rows: int = 31, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """Traces a heightfield's visible normals (`microsim trace vndf --surface`): the dict trace_vndf returns."""

def masking(surface: "Heightfield", theta: float, phi: float = 0.0, *, samples: int = 1000000, seed: int = 1,
            bins: int = 10, theta_l: Optional[float] = None, phi_l: float = 0.0, cone: float = 5.0,
            grazing_share: float = 0.02, geometry: str = "triangles", threads: int = 0,
            progress: Progress = None) -> dict[str, Any]:
    """Masking measured on a heightfield (`microsim trace masking --surface`): the JSON "masking" object."""

def smith_walk(alpha: Alpha, theta: float, phi: float = 0.0, *, material: str = "mirror", ndf: str = "ggx",
               heights: str = "uniform", walk_kernel: str = "scalar", rays: int = 1000000, seed: int = 1,
               max_order: int = 100, rows: int = 16, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """The Smith random walk (Heitz et al. 2016; `microsim scatter --model smith-walk [--walk-kernel K]`):
    {'summary' (albedos per order), 'paths', 'partial', 'mean_weight' and 'stderr' (channels, 5, rows, cols),
    'binning' (geometry)}. walk_kernel 'lanes': the SIMD walk (GGX, uniform heights, not Lambertian)."""

def analytic_scatter(alpha: Alpha, theta: float, phi: float = 0.0, *, material: str = "mirror", ndf: str = "ggx",
                     rows: int = 16, threads: int = 0, progress: Progress = None) -> dict[str, Any]:
    """The exact single scattering (`microsim scatter --model analytic`): {'summary', 'order1' (channels, rows,
    cols): order-1 weight per launched path in each bin, 'binning'}."""

def scatter_surface(surface: "Heightfield", theta: float, phi: float = 0.0, *, material: str = "mirror",
                    rays: int = 1000000, seed: int = 1, max_order: int = 100, rows: int = 16, threads: int = 0,
                    progress: Progress = None) -> dict[str, Any]:
    """Multiple scattering traced on a heightfield (`microsim scatter --surface`): the dict smith_walk returns."""

def read_histogram(path: str) -> dict[str, Any]:
    """Reads a histogram EXR of `microsim trace vndf --out`: the dict trace_vndf returns."""

class Heightfield:
    """A periodic heightfield microsurface: heights on an N x N grid over a tile of side L."""
    def __init__(self, heights: npt.ArrayLike, tile_size: float) -> None: ...
    @property
    def resolution(self) -> int: ...
    @property
    def tile_size(self) -> float: ...
    @property
    def heights(self) -> np.ndarray: ...  # read-only float32 (N, N) view, no copy
    metadata: dict[str, str]
    def save(self, path: str) -> None: ...

def load_heightfield(path: str, tile_size: Optional[float] = None) -> Heightfield: ...

def build_surface(assembly: str = "smith", alpha: Alpha = 0.5, *, resolution: int = 1024, seed: int = 1,
                  corr_cells: float = 0.0, tile_size: float = 1.0, iterations: int = 0, check_range: bool = True,
                  progress: Progress = None) -> Heightfield:
    """Builds a periodic heightfield microsurface (`microsim surface build`): same heights for the same seed."""

def check_bsdf(sample: Callable[[np.ndarray, np.ndarray], Tuple[np.ndarray, np.ndarray, np.ndarray]],
               eval: Callable[[np.ndarray, np.ndarray], np.ndarray],
               pdf: Optional[Callable[[np.ndarray, np.ndarray], np.ndarray]] = None, *,
               bsdf: str, alpha: Alpha, channels: int = 1, transport: str = "radiance",
               masking: str = "height-correlated", sampling: str = "vndf", samples: int = 200000, seed: int = 1,
               level: float = 0.01, arithmetic: str = "float32", reference: str = "single-scattering",
               views: Optional[Sequence[Union[float, Tuple[float, float]]]] = None, stochastic_eval: bool = False,
               html: Optional[Union[str, "os.PathLike[str]"]] = None) -> Dict[str, Any]:
    """The whole BSDF battery (`microsim check-bsdf`) on vectorised numpy callables, with its options (reference
    'single-scattering', 'smith-walk' or 'none'; views THETA or (THETA, PHI) in degrees; html a report path): the
    report as a dict (check-bsdf's JSON, with 'passed')."""
    ...

def check_bsdf_files(dump: Union[str, "os.PathLike[str]", np.ndarray], eval: Union[str, "os.PathLike[str]", np.ndarray],
                     *, theta: float, phi: float = 0.0,
                     cells: Optional[Union[str, "os.PathLike[str]", np.ndarray]] = None,
                     columns: str = "x,y,z,pdf,weight", eval_columns: str = "wi,wo,value,pdf", frame: str = "z-up",
                     lost: int = 0, albedo: Optional[float] = None, level: float = 0.01) -> Dict[str, Any]:
    """One BSDF's consistency with itself from a sample dump and its eval file at the same rows, paths or arrays
    (N, K) of their rows (`microsim check-bsdf-files`): the report as a dict (its JSON, with 'passed')."""
    ...

def compare_scattering(files: Sequence[str], *, analytic: bool = False, orders: Optional[str] = None,
                       level: float = 0.01, threads: int = 0, progress: Progress = None) -> Dict[str, Any]:
    """Two or three scatter files or traced histograms compared (`microsim compare-scattering`): its JSON as a
    dict, with 'rejected' and 'passed'."""
    ...

def merge(parts: Sequence[Union[str, "os.PathLike[str]"]], *, out: Optional[Union[str, "os.PathLike[str]"]] = None,
          json: Optional[Union[str, "os.PathLike[str]"]] = None,
          surface: Optional[Union[str, "os.PathLike[str]"]] = None, progress: Progress = None) -> Dict[str, Any]:
    """The JSON parts of one run (`trace vndf --shard` on the ellipsoid or a heightfield, `scatter --shard`,
    `trace masking --shard`, `validate --shard`, `stability --shard`) joined bit for bit (`microsim merge`):
    the dict its --json writes; `out` the merged .exr histogram; `surface` the heightmap of heightfield parts.
    Parts of different runs, missing or repeated blocks, or an EXR part raise ValueError naming them."""
    ...
