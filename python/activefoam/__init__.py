"""activefoam: the Python client of foamd (python/README.md).

    from activefoam import Client
    c = Client("host:50051")
    job = c.submit({"scene": "doublet", "duration_s": 600}, preset="draft")
    job.wait(progress=True); job.samples(); job.results()
"""

from activefoam.client import Client, Job, Sweep

__all__ = ["Client", "Job", "Sweep"]
