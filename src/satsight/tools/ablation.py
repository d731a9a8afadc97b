"""Ablation of the radiative model, in the manner of the paper's Table 4.

The frames of a scenario are rendered once as a **reference** (the GGX
metallic/roughness/IOR model of Eq. 18-20 that defines the materials, the exact collimated
Sun, the sampled environment expanded to SH order 8, no inter-reflection unless asked for,
many samples per pixel) and then with each **variant**, which changes one thing:

* ``improved_phong`` / ``phong``: the reflection model (Eq. 17 / Eq. 16), exact Sun, each
  part's coefficients FITTED to its GGX material (``satsight.brdf.reference_fit``: a
  weighted least-squares fit of the Phong model to the material's GGX BRDF over the
  hemisphere of incidence and viewing directions), so the error measures what each Phong
  form can do at its best;
* ``improved_phong_mapped`` / ``phong_mapped``: the same models with the coefficients
  derived from the GGX parameters by the heuristic mapping of ``satsight.scene.materials``
  (``Material.mapped_phong_coefficients``), which renders what a scenario with
  ``render.brdf: phong`` or ``improved_phong`` shows;
* ``sh3_sun`` / ``sh4_sun``: the Sun replaced by its SH expansion of order 3 / 4 (Eq. 10),
  the environment truncated to the same order;
* ``exact``: the reference model itself at the variants' sample count (the noise floor).

Every run of a frame uses the frame's seed (common random numbers): a variant's passes see
the same samples as the reference's first passes, so the noise that separates them is
small and the differences measure the model change.

Metrics per variant, averaged over frames, on the pixels where either image sees the target:

* MSE of the radiance, (W m^-2 sr^-1)^2, over all three channels;
* PSNR = 10 log10(peak^2 / MSE) dB with peak = the reference's largest radiance in the frame;
* mean angular error: the angle in degrees between the RGB radiance vectors of reference
  and variant, averaged over pixels where both are non-zero (a colour/spectral-angle
  error, blind to brightness).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.config.scenario import Scenario
from satsight.errors import SatsightError
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.mesh import TargetMesh
from satsight.vectors import angle_between_rad

VARIANTS: dict[str, dict] = {
    "improved_phong": {"brdf": "improved_phong"},
    "phong": {"brdf": "phong"},
    "improved_phong_mapped": {"brdf": "improved_phong"},
    "phong_mapped": {"brdf": "phong"},
    "sh3_sun": {"sun": "sh", "sh_order": 3},
    "sh4_sun": {"sun": "sh", "sh_order": 4},
    "exact": {},
}
# Variants whose parts render with Phong coefficients fitted to their GGX materials: the
# variant's name -> the fitted model. The other Phong variants use the mapped coefficients.
FITTED_VARIANTS: dict[str, str] = {"improved_phong": "improved_phong", "phong": "phong"}
# The environment (earthshine, moonshine) of the reference and of the non-SH variants is
# expanded to this order; the sh3/sh4 variants truncate Sun and environment alike.
REFERENCE_SH_ORDER = 8
METRIC_COLUMNS = ("variant", "mse_w2_m4_sr2", "psnr_db", "mean_angular_error_deg", "frames")


@dataclass(frozen=True)
class FrameMetrics:
    mse_w2_m4_sr2: float
    psnr_db: float
    mean_angular_error_deg: float


def image_metrics(reference: np.ndarray, image: np.ndarray) -> FrameMetrics:
    """MSE, PSNR and mean RGB angular error of ``image`` against ``reference`` (H, W, 3).

    Pixels count where either image is non-zero; the angle needs both non-zero.
    """
    ref = np.asarray(reference, dtype=np.float64)
    img = np.asarray(image, dtype=np.float64)
    if ref.shape != img.shape or ref.ndim != 3 or ref.shape[-1] != 3:
        raise SatsightError(f"images must both be (H, W, 3); got {ref.shape} and {img.shape}")
    ref_norm = np.linalg.norm(ref, axis=-1)
    img_norm = np.linalg.norm(img, axis=-1)
    used = (ref_norm > 0) | (img_norm > 0)
    if not used.any():
        raise SatsightError("neither image sees the target: nothing to compare")
    mse = float(np.mean((ref[used] - img[used]) ** 2))
    peak = float(ref.max())
    psnr = math.inf if mse == 0.0 else 10.0 * math.log10(peak * peak / mse)
    both = (ref_norm > 0) & (img_norm > 0)
    angle = np.degrees(angle_between_rad(ref[both], img[both]))
    return FrameMetrics(mse, psnr, float(angle.mean()) if angle.size else 0.0)


def ablation_camera(camera: PinholeCamera, width_px: int | None) -> PinholeCamera:
    """The scenario's camera with the same field of view on ``width_px`` columns."""
    if width_px is None or width_px >= camera.width_px:
        return camera
    scale = camera.width_px / width_px
    return PinholeCamera(
        camera.focal_length_m,
        camera.pixel_pitch_m * scale,
        width_px,
        max(1, round(camera.height_px / scale)),
    )


@dataclass(frozen=True)
class AblationResult:
    rows: list[dict]
    images: dict[str, list[np.ndarray]]  # "reference" and each variant: one image per frame
    # The Phong fits of the materials the target's parts use, by material name
    # (``satsight.brdf.reference_fit.PhongModelFits``).
    fits: dict = field(default_factory=dict)


def fitted_phong_meshes(mesh: TargetMesh, masking: str) -> tuple[dict[str, TargetMesh], dict]:
    """({variant: the mesh with each used material's ``phong`` set to that variant's fit},
    {material name: its ``PhongModelFits``}) for the ``FITTED_VARIANTS``.

    masking: the GGX masking term of the reference, which the fits sample."""
    from satsight.brdf.reference_fit import fit_phong_to_ggx

    used = sorted(set(mesh.part_materials))
    fits = {name: fit_phong_to_ggx(mesh.materials[name], masking) for name in used}
    meshes = {}
    for variant, model in FITTED_VARIANTS.items():
        materials = dict(mesh.materials)
        materials.update({name: fits[name].material_for(model) for name in used})
        meshes[variant] = dataclasses.replace(mesh, materials=materials)
    return meshes, fits


def fit_rows(fits: dict) -> list[dict]:
    """One row per (material, fitted model): the fitted coefficients (kd, ks per channel,
    g, a, b, c) and the fit's metrics against the material's GGX BRDF."""
    rows = []
    for name, result in fits.items():
        for model, fit in result.fits.items():
            rows.append(
                {
                    "material": name,
                    "model": model,
                    **fit.summary(),
                    "geometries": result.n_geometries,
                }
            )
    return rows


def run_ablation(
    scenario: Scenario,
    samples_per_pixel: int = 16,
    reference_samples_per_pixel: int = 256,
    width_px: int | None = 384,
    max_frames: int | None = None,
    on_render: Callable[[str, int], None] | None = None,
    bounces: int = 0,
    on_plan: Callable[[int], None] | None = None,
) -> AblationResult:
    """Render the reference and every variant for the scenario's frames; see module doc.

    bounces: inter-reflections in every run. The default 0 compares the models where they
    act first, at the visible surface; with bounces the rare bright inter-reflection paths
    (Sun light reflected by a glossy part into another) add Monte Carlo noise that grows
    the noise floor far above the model differences at affordable sample counts.
    """
    from satsight.frame_light import frame_light
    from satsight.pipeline import frame_seed, planned_frames

    if samples_per_pixel < 1 or reference_samples_per_pixel < samples_per_pixel:
        raise SatsightError(
            "need 1 <= samples_per_pixel <= reference_samples_per_pixel, got "
            f"{samples_per_pixel} and {reference_samples_per_pixel}"
        )
    mesh = scenario.target.build(scenario.sun.band_nm)
    camera = ablation_camera(scenario.camera.build(), width_px)
    reference_scenario = scenario.model_copy(
        update={"render": scenario.render.model_copy(update={"sh_order": REFERENCE_SH_ORDER})}
    )
    track, indices = planned_frames(reference_scenario, mesh)
    if max_frames is not None:
        indices = indices[:max_frames]
    lights = [frame_light(reference_scenario, track, i) for i in indices]
    # A frame without light (in the umbra, seeing only the Earth's night side) renders
    # black and has nothing to compare.
    lit = [
        k
        for k, light in enumerate(lights)
        if light.sun_irradiance_w_m2 > 0 or np.any(light.sh_radiance_w_m2_sr != 0)
    ]
    if not lit:
        raise SatsightError(
            "no frame of the scenario is lit (all in the Earth's shadow); nothing to ablate"
        )
    indices, lights = indices[lit], [lights[k] for k in lit]
    if on_plan is not None:
        on_plan(len(indices))
    base = scenario.render.settings().with_(
        brdf="ggx",
        sun="delta",
        environment="sampled",
        supersampling=1,
        sh_order=REFERENCE_SH_ORDER,
        bounces=bounces,
    )
    runs: dict[str, RenderSettings] = {
        "reference": base.with_(samples_per_pixel=reference_samples_per_pixel)
    }
    for name, change in VARIANTS.items():
        runs[name] = base.with_(samples_per_pixel=samples_per_pixel, **change)
    fitted_meshes, fits = fitted_phong_meshes(mesh, base.ggx_masking)
    images: dict[str, list[np.ndarray]] = {}
    for name, settings in runs.items():
        renderer = Renderer(fitted_meshes.get(name, mesh), settings, scenario.render.variant)
        images[name] = []
        for index, (plan_index, light) in enumerate(zip(indices, lights, strict=True)):
            pose = track.cam_from_body(plan_index)
            # Common random numbers: every run of a frame uses the same seed, so a variant's
            # passes use the same samples as the reference's first passes and their
            # difference shows the model change, not independent Monte Carlo noise.
            image = renderer.render(
                camera, pose, light, seed=frame_seed(scenario.seed, int(plan_index))
            )
            images[name].append(image.radiance_w_m2_sr)
            if on_render is not None:
                on_render(name, index)
    rows = []
    for name in VARIANTS:
        pairs = zip(images["reference"], images[name], strict=True)
        metrics = [image_metrics(r, v) for r, v in pairs]
        rows.append(
            {
                "variant": name,
                "mse_w2_m4_sr2": float(np.mean([m.mse_w2_m4_sr2 for m in metrics])),
                "psnr_db": float(np.mean([m.psnr_db for m in metrics])),
                "mean_angular_error_deg": float(
                    np.mean([m.mean_angular_error_deg for m in metrics])
                ),
                "frames": len(metrics),
            }
        )
    return AblationResult(rows, images, fits)


def write_csv(path: Path, rows: list[dict]) -> None:
    with Path(path).open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=METRIC_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)


def write_figure(path: Path, result: AblationResult, title: str) -> None:
    """Bar charts of the three metrics and, per variant, its first frame and error map."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [row["variant"] for row in result.rows]
    columns = len(names) + 1
    fig = plt.figure(figsize=(3.0 * columns, 8.5), layout="constrained")
    grid = fig.add_gridspec(3, columns)
    for k, (key, label) in enumerate(
        (
            ("mse_w2_m4_sr2", "MSE (W m$^{-2}$ sr$^{-1}$)$^2$"),
            ("psnr_db", "PSNR (dB)"),
            ("mean_angular_error_deg", "mean angular error (deg)"),
        )
    ):
        ax = fig.add_subplot(grid[0, 2 * k : 2 * k + 2] if 2 * k + 2 <= columns else grid[0, -1])
        ax.bar(names, [row[key] for row in result.rows], color="tab:blue")
        ax.set_title(label, fontsize=9)
        ax.tick_params(axis="x", labelrotation=45, labelsize=8)
    reference = result.images["reference"][0]
    peak = float(reference.max()) or 1.0

    def show(ax, image, caption):
        # One linear scale for all panels (the reference's peak), display gamma 2.2.
        ax.imshow(np.clip(image / peak, 0.0, 1.0) ** (1.0 / 2.2))
        ax.set_title(caption, fontsize=8)
        ax.set_axis_off()

    show(fig.add_subplot(grid[1, 0]), reference, "reference (frame 0)")
    fig.add_subplot(grid[2, 0]).set_axis_off()
    for k, name in enumerate(names, start=1):
        image = result.images[name][0]
        show(fig.add_subplot(grid[1, k]), image, name)
        ax = fig.add_subplot(grid[2, k])
        error = np.linalg.norm(image - reference, axis=-1) / peak
        shown = ax.imshow(error, cmap="magma", vmin=0.0, vmax=max(0.05, float(error.max())))
        ax.set_title(f"|{name} - reference| / peak", fontsize=8)
        ax.set_axis_off()
        fig.colorbar(shown, ax=ax, shrink=0.7)
    fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
