"""Effect of inflating each noise parameter on the model PSD, paper Appendix Table 3 settings (Fig. 7); a PNG
and, with config figures.format svg or pdf, a copy in that format."""

from pathlib import Path

from imupipe.io import run_job


def main(path_out: str, copies: list) -> None:
    from imupipe.io import atomic_path
    from imupipe.plot import plot_inflation_effect, save_figure

    fig = plot_inflation_effect()
    for path in copies:
        with atomic_path(path) as tmp:
            fig.savefig(str(tmp), format=Path(path).suffix.lstrip("."), dpi=150)
    save_figure(fig, path_out)


if __name__ == "__main__":
    o = snakemake.output
    run_job(main, snakemake.log[0], path_out=o.figure, copies=[o.copies] if isinstance(o.copies, str) else list(o.copies))
