import pytest


@pytest.fixture(scope="session", autouse=True)
def fresh_codegen_cache(tmp_path_factory):
    """Every test session compiles the NMPC code from scratch (as a fresh machine would)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("AERORELAY_CACHE", str(tmp_path_factory.mktemp("codegen")))
    yield
    mp.undo()
