"""`garment make-body`: rebuild the embedded default body from the open anny human.

Needs the optional extra (`pip install 'garment[body]'`; in a checkout `pip install -e ".[body]"`); normal runs
only read the packaged `core/assets/default_body.npz`, which `garment make-body --out core/assets/default_body.npz
--overwrite` rebuilds in a checkout.
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from core.body import DEFAULT_BODY_RESOURCE
from garmentcli.common import SEED_RANGE, OutputPath
from formats.atomic import atomic_file


@click.command(name="make-body")
@click.option("--out", "out", type=OutputPath(dir_okay=False, path_type=Path), default=DEFAULT_BODY_RESOURCE,
              show_default=True, help="Output .npz (the shipped body: core/assets/default_body.npz in a checkout; "
              "an installed package is never written).")
@click.option("--samples", type=click.IntRange(min=20), default=400, show_default=True,
              help="Adult phenotype samples for the shape PCA.")
@click.option("--seed", type=SEED_RANGE, default=0, show_default=True, help="Random seed of the phenotype sampler.")
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
def make_body(out: Path, samples: int, seed: int, overwrite: bool) -> None:
    """Build the default SMPL-format body (24 joints, 10 betas) from anny and save it.

    anny builds a model cache of about 800 MB on its first use (a few minutes; ANNY_CACHE_DIR sets where).
    """
    out = Path(out)
    if out.suffix != ".npz":
        raise click.BadParameter(f"expected a path ending in .npz, got '{out}'", param_hint="--out")
    if out.exists() and not overwrite:
        raise click.ClickException(f"output '{out}' exists: pass --overwrite to replace it")
    try:
        from core.anny_body import build_default_body_arrays
        arrays = build_default_body_arrays(n_samples=samples, seed=seed)
    except (ImportError, RuntimeError) as exc:
        raise click.ClickException(f"make-body: {exc}") from None
    except OSError as exc:  # anny's model cache (about 800 MB, built on first use) cannot be written there
        where = f" '{exc.filename}'" if exc.filename else ""
        raise click.ClickException(f"make-body: anny's model cache{where}: {exc.strerror or exc}: set "
                                   "ANNY_CACHE_DIR to a writable folder with about 1 GB free") from None
    with atomic_file(out) as tmp:
        np.savez_compressed(tmp, **arrays)
    click.echo(f"wrote {out}: {arrays['v_template'].shape[0]} vertices, "
               f"height {float(arrays['stats_mean_height_m']):.3f} m, "
               f"PCA residual {float(arrays['stats_pca_residual_mean_mm']):.2f} mm mean, "
               f"joint fit {float(arrays['stats_joint_fit_mean_mm']):.2f} mm mean "
               f"({out.stat().st_size / 1e6:.1f} MB)")
