import pytest
from hypothesis import HealthCheck, settings

# No hypothesis test has a deadline: on a busy 2-core machine a draw's time says nothing about its
# correctness (a newcomer's make test went red on a 200 ms deadline while another process ran). Speed
# targets live in benchmarks (aerorelay bench), not in unit tests.
settings.register_profile("aerorelay", deadline=None, suppress_health_check=[HealthCheck.too_slow], print_blob=True)
settings.load_profile("aerorelay")


@pytest.fixture(scope="session", autouse=True)
def fresh_codegen_cache(tmp_path_factory, request):
    """Every test run compiles the NMPC code from scratch (as a fresh machine would), once: pytest-xdist's workers
    share one cache folder (its builders serialize on a file lock and publish whole libraries, as dask workers do:
    ``store.codegen.shared_library``), so no C source is compiled by both."""
    mp = pytest.MonkeyPatch()
    if not hasattr(request.config, "workerinput"):  # not a pytest-xdist worker
        folder = tmp_path_factory.mktemp("codegen")
    else:  # the workers' temporary folders share this run's parent
        folder = tmp_path_factory.getbasetemp().parent / "codegen"
        folder.mkdir(exist_ok=True)
    mp.setenv("AERORELAY_CACHE", str(folder))
    # pytest-xdist runs a worker per core: their fleets step their relays one after another (threads measured apart:
    # tests/sim/test_networks_at_scale.py)
    mp.setenv("AERORELAY_RELAY_THREADS", "1")
    yield
    mp.undo()
