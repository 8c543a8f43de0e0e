import pytest
from hypothesis import HealthCheck, settings

# No hypothesis test has a deadline: on a busy 2-core machine a draw's time says nothing about its
# correctness (a newcomer's make test went red on a 200 ms deadline while another process ran). Speed
# targets live in benchmarks (aerorelay bench), not in unit tests.
settings.register_profile("aerorelay", deadline=None, suppress_health_check=[HealthCheck.too_slow], print_blob=True)
settings.load_profile("aerorelay")


@pytest.fixture(scope="session", autouse=True)
def fresh_codegen_cache(tmp_path_factory):
    """Every test session compiles the NMPC code from scratch (as a fresh machine would)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("AERORELAY_CACHE", str(tmp_path_factory.mktemp("codegen")))
    yield
    mp.undo()
