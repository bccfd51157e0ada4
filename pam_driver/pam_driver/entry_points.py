"""The console scripts of pam_driver (setup.py), quiet on a stop during start-up
(pam_model.cli.startup: the nodes keep the quiet handlers until run_node installs its own)."""

from pam_model.cli.startup import entry

sim_node = entry('pam_driver.sim_node:main', own_handlers=True)
driver_node = entry('pam_driver.driver_node:main', own_handlers=True)
pam_emulator = entry('pam_driver.emulator:main')
