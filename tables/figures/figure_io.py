# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared by the plotting scripts: the non-interactive pyplot, the table and figure directories from
the command line, reading a table (CSV with leading # lines), the axis labels every figure uses for
the same quantity, and atomic output of each figure as PDF (vector, for print) and 300-dpi PNG
(temporary file beside the target, rename)."""
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


# One label per quantity, in every figure (the paper's symbols).
BETA = r"$\beta$"
RATIO = r"$\langle K_1\rangle/\langle K_2\rangle$"
MU1 = r"$\mu_1$"
L2 = r"$l_2$"

PNG_DPI = 300


def save_figure(fig, directory, name):
    """Writes `fig` as directory/NAME.pdf and directory/NAME.png (300 dpi), NAME = `name` without
    its .png, each through a temporary file renamed into place."""
    import matplotlib.pyplot as plt

    stem = name[:-4] if name.endswith(".png") else name
    for suffix, options in ((".pdf", {}), (".png", {"dpi": PNG_DPI})):
        fd, tmp = tempfile.mkstemp(prefix=stem + ".tmp.", suffix=suffix, dir=directory)
        os.close(fd)
        try:
            # No creation date in the PDF: an unchanged figure is an unchanged file.
            metadata = {"CreationDate": None} if suffix == ".pdf" else {}
            fig.savefig(tmp, bbox_inches="tight", metadata=metadata, **options)
            os.chmod(tmp, 0o644)
            os.replace(tmp, os.path.join(directory, stem + suffix))
        except BaseException:
            os.unlink(tmp)
            raise
    plt.close(fig)
