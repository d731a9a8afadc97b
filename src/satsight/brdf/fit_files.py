"""What a BRDF fit writes: its material-library entry (YAML), the plot, and the report of
``satsight fit-brdf`` (:func:`fit_brdf_command`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from satsight.brdf.fit import BrdfFit, fit_brdf
from satsight.brdf.measurements import read_brdf_csv
from satsight.errors import SatsightError

# ----------------------------------------------------------------------------------------
# Material-library entry (YAML) and the command


def _is_rgb(channel_names: tuple[str, ...]) -> bool:
    return tuple(c.upper() for c in channel_names) == ("R", "G", "B")


def _channel_value(values: np.ndarray, channel_names: tuple[str, ...]):
    values = [float(v) for v in values]
    return values[0] if len(values) == 1 else values


def material_entry(fit: BrdfFit) -> dict:
    """The fit as a material-library entry: model, parameters (kd / kd_rgb, ks / ks_rgb, g,
    a, b, c, or base_color / base_color_rgb, metallic, roughness, ior, masking), their
    1-sigma uncertainties, channels, metrics, energy check, fit details and source."""
    suffix = "_rgb" if _is_rgb(fit.channel_names) else ""
    key = {"kd": "kd", "ks": "ks", "base": "base_color"}

    def section(values: dict) -> dict:
        out = {}
        for name, value in values.items():
            if isinstance(value, np.ndarray):
                out[key[name] + suffix] = _channel_value(value, fit.channel_names)
            else:
                out[name] = float(value)
        return out

    parameters = section(fit.parameters)
    if fit.model == "ggx":
        parameters["masking"] = fit.masking
    return {
        "model": fit.model,
        "parameters": parameters,
        "parameters_std": section(fit.parameter_std),
        "channels": {"kind": fit.channel_kind, "names": list(fit.channel_names)},
        "metrics": fit.metrics.as_dict(),
        "energy": {
            "max_directional_albedo": float(fit.max_albedo),
            "at_theta_i_deg": float(fit.max_albedo_theta_deg),
        },
        "fit": {
            "n_measurements": fit.n_measurements,
            "n_parameters": len(fit.names),
            "weighted_by_uncertainty": fit.weighted,
            "reduced_chi2": float(fit.reduced_chi2),
            "parameters_at_bounds": list(fit.at_bounds),
            "converged": fit.success,
            "optimizer_message": fit.message,
        },
        "source": fit.source,
        "library_brdf": library_brdf_block(fit),
    }


_LIBRARY_KEYS = {
    "metallic": "metallic",
    "roughness": "roughness",
    "ior": "ior",
    "g": "gloss_exponent_g",
    "a": "fresnel_exponent_a",
    "b": "lobe_decay_b",
    "c": "diffuse_exponent_c",
}


def library_brdf_block(fit: BrdfFit) -> dict:
    """The fitted shape parameters as entries ``{value, source}`` of a material-library
    ``brdf:`` block (``satsight.scene.material_library`` names: metallic, roughness, ior,
    gloss_exponent_g, fresnel_exponent_a, lobe_decay_b, diffuse_exponent_c); per-channel
    reflectances stay in ``parameters``."""
    where = fit.source.get("csv", "?")
    source = f"{fit.model} fit to {where}, PSNR {fit.metrics.psnr_db:.1f} dB (satsight.brdf.fit)"
    return {
        _LIBRARY_KEYS[name]: {"value": float(value), "source": source}
        for name, value in fit.parameters.items()
        if name in _LIBRARY_KEYS
    }


def write_fit_yaml(fit: BrdfFit, path: str | Path) -> Path:
    """Write ``material_entry(fit)`` as YAML."""
    path = Path(path)
    path.write_text(
        yaml.safe_dump(material_entry(fit), sort_keys=False, default_flow_style=None),
        encoding="utf-8",
    )
    return path


@dataclass(frozen=True)
class FitReport:
    """What ``fit_brdf_command`` did: the fit and the files it wrote."""

    fit: BrdfFit
    csv_path: Path
    yaml_path: Path
    plot_path: Path

    def table(self) -> str:
        """Plain-text summary: parameters with 1-sigma uncertainties, metrics, files."""
        fit = self.fit
        lines = [
            f"BRDF fit: {fit.model} to {self.csv_path} "
            f"({fit.n_measurements} measurements, channels: {', '.join(fit.channel_names)})",
            f"{'parameter':<22}{'value':>14}{'1-sigma':>14}",
        ]
        for name, value, std in zip(fit.names, fit.values, fit.std, strict=True):
            lines.append(f"{name:<22}{value:>14.6g}{std:>14.3g}")
        m = fit.metrics
        lines += [
            f"MSE {m.mse_sr2:.4g} sr^-2, PSNR {m.psnr_db:.2f} dB (peak {m.peak_per_sr:.4g} "
            f"sr^-1), angular error {m.angular_error_deg:.3f} deg ({m.angular_error_kind})",
            f"largest directional albedo {fit.max_albedo:.4f} (theta_i = "
            f"{fit.max_albedo_theta_deg:g} deg)",
        ]
        if fit.at_bounds:
            lines.append("at a bound (uncertainty not meaningful): " + ", ".join(fit.at_bounds))
        if not fit.success:
            lines.append(f"optimizer did not converge: {fit.message}")
        lines += [f"wrote {self.yaml_path}", f"wrote {self.plot_path}"]
        return "\n".join(lines)


def fit_brdf_command(
    csv_path: str | Path,
    model: str,
    out_dir: str | Path,
    masking: str = "schlick",
) -> FitReport:
    """``satsight fit-brdf CSV --model M --out DIR``: read the table, fit the model, write
    ``DIR/<csv stem>_<model>.yaml`` (``material_entry``) and
    ``DIR/<csv stem>_<model>_plane.png`` (measured and fitted BRDF in the plane of
    incidence), and return the report (prints nothing)."""
    from satsight.brdf.plot import plot_plane_of_incidence

    csv_path = Path(csv_path)
    measurements = read_brdf_csv(csv_path)
    fit = fit_brdf(measurements, model, masking=masking)
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise SatsightError(f"cannot create the output folder {out}: {err}") from None
    stem = f"{csv_path.stem}_{model}"
    yaml_path = write_fit_yaml(fit, out / f"{stem}.yaml")
    plot_path = plot_plane_of_incidence(
        measurements,
        fit.evaluate,
        out / f"{stem}_plane.png",
        title=f"{csv_path.name}: {model}, PSNR {fit.metrics.psnr_db:.1f} dB",
    )
    return FitReport(fit=fit, csv_path=csv_path, yaml_path=yaml_path, plot_path=plot_path)
