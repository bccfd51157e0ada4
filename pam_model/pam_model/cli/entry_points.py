"""The console scripts of pam_model (setup.py), quiet on a stop during start-up (startup)."""

from .startup import entry

pam_simulate = entry('pam_model.cli.simulate:main')
pam_kappa = entry('pam_model.cli.kappa:main')
