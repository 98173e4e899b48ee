"""One-line plots of a run's series with matplotlib (Agg: no display needed)."""

from .needs import need, need_or_exit


def pyplot():
    """matplotlib.pyplot on the Agg backend (MissingModule naming python3-matplotlib)."""
    need("matplotlib", "python3-matplotlib").use("Agg")
    return need("matplotlib.pyplot", "python3-matplotlib")


def pyplot_or_exit(tool):
    """pyplot() for a script: without matplotlib, the reason as `tool: ...` and exit 2."""
    need_or_exit(tool, "matplotlib", "python3-matplotlib").use("Agg")
    return need_or_exit(tool, "matplotlib.pyplot", "python3-matplotlib")


def save_figure(fig, path, dpi=110):
    """Lays `fig` out, writes it to `path` (PNG by the name) and closes it; returns `path`."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
    return path


def plot_columns(table, y=None, x=None, out=None, ax=None):
    """Lines of `table`'s columns `y` (a name, a list, or None: all but x and step) against
    `x` (None: time, else the first column), labelled by column; saved to `out` when given."""
    if x is None:
        x = "time" if "time" in table else table.header[0]
    names = [y] if isinstance(y, str) else list(y or (h for h in table.header
                                                      if h not in (x, "step")))
    for n in [x] + names:
        table[n]  # a KeyError that names the file and its columns, before drawing
    plt = pyplot()
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4))
    for n in names:
        ax.plot(table[x], table[n], lw=1, label=n)
    ax.set_xlabel(x)
    if len(names) == 1:
        ax.set_ylabel(names[0])
    else:
        ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    if out is not None:
        (fig or ax.figure).tight_layout()
        (fig or ax.figure).savefig(out, dpi=110)
    if fig is not None and out is not None:
        plt.close(fig)
    return ax
