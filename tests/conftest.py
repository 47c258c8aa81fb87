import os

from hypothesis import HealthCheck, settings

settings.register_profile("lenticalib", derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("ci", parent=settings.get_profile("lenticalib"), max_examples=40)
settings.load_profile("ci" if os.environ.get("CI") else "lenticalib")
