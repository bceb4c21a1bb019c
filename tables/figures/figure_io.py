"""Shared by the plotting scripts: the non-interactive pyplot, the table and figure directories from
the command line, reading a table (CSV with leading # lines) and atomic PNG output (temporary file
beside the target, rename)."""
import csv
import os
import tempfile


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def table_dirs(argv):
    """(TABLES_DIR, TABLES_DIR/figures) from the script's arguments (default: the current folder)."""
    tables = argv[1] if len(argv) > 1 else "."
    return tables, os.path.join(tables, "figures")


def read_table(directory, name):
    """The rows of directory/name as dicts, skipping the # comment lines."""
    with open(os.path.join(directory, name)) as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


def save_png(fig, directory, name, dpi=130):
    """Writes `fig` to directory/name through a temporary file renamed into place."""
    import matplotlib.pyplot as plt

    fd, tmp = tempfile.mkstemp(prefix=name + ".tmp.", suffix=".png", dir=directory)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight")
        os.chmod(tmp, 0o644)
        os.replace(tmp, os.path.join(directory, name))
    except BaseException:
        os.unlink(tmp)
        raise
    plt.close(fig)
