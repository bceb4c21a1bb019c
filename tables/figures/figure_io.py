"""Atomic PNG output shared by the plotting scripts: temporary file beside the target, rename."""
import os
import tempfile


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
