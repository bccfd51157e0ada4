"""Repository-wide pytest options. `--repeat N` runs every selected test N times in one session
(one module domain and probe context, as in a full run): the soak runs of scripts/soak.sh."""


def pytest_addoption(parser):
    parser.addoption('--repeat', type=int, default=1, metavar='N',
                     help='run each selected test N times (soak runs, see scripts/soak.sh)')


def pytest_generate_tests(metafunc):
    rounds = metafunc.config.getoption('repeat')
    if rounds > 1:
        metafunc.fixturenames.append('soak_round')
        metafunc.parametrize('soak_round', range(1, rounds + 1))
