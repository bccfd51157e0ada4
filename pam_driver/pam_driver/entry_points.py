"""The console scripts of pam_driver (setup.py), quiet on a stop during start-up
(pam_model.cli.startup: the nodes keep the quiet handlers until run_node installs its own)."""

from pam_model.cli.startup import entry

sim_node = entry('pam_driver.sim_node:main', own_handlers=True)
profile_player = entry('pam_driver.profile_player:main', own_handlers=True)
driver_node = entry('pam_driver.driver_node:main', own_handlers=True)
bag_record = entry('pam_driver.bag_record:main', own_handlers=True)
bag_play = entry('pam_driver.bag_play:main', own_handlers=True)
pam_emulator = entry('pam_driver.emulator:main')
pam_bag_info = entry('pam_driver.bag_info:main')
pam_bag_recover = entry('pam_driver.bag_recover:main')
