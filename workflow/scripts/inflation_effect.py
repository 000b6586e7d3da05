"""Effect of inflating each noise parameter on the model PSD, paper Appendix Table 3 settings (Fig. 7)."""

from imupipe.io import run_job


def main(path_out: str) -> None:
    from imupipe.plot import plot_inflation_effect, save_figure

    save_figure(plot_inflation_effect(), path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], path_out=snakemake.output.figure)
