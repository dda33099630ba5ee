"""activefoam: the Python client of foamd (python/README.md).

    from activefoam import Client
    c = Client("host:50051")
    job = c.submit({"scene": "doublet", "duration_s": 600}, preset="standard")
    job.wait(progress=True); job.samples(); job.results()

The study tool is activefoam.study (python3 -m activefoam.study, or foam-study).
"""

# The package's version, read by pyproject.toml; python/CMakeLists.txt checks that it is the
# project's (CMakeLists.txt).
__version__ = "0.1.0"

from activefoam.client import Client, Job, Sweep  # noqa: E402

__all__ = ["Client", "Job", "Sweep", "__version__"]
