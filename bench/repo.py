"""The repository the benchmark scripts run from, and its commit for their result files."""
import os
import subprocess

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def git_commit():
    """The checkout's HEAD commit, or "unknown" outside a git checkout."""
    try:
        out = subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], check=True,
                             capture_output=True, text=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
