"""The console scripts of pam_bag (setup.py), quiet on a stop during start-up
(pam_model.cli.startup: the nodes keep the quiet handlers until run_node installs its own)."""

from pam_model.cli.startup import entry

bag_record = entry('pam_bag.bag_record:main', own_handlers=True)
bag_play = entry('pam_bag.bag_play:main', own_handlers=True)
pam_bag_info = entry('pam_bag.bag_info:main')
pam_bag_recover = entry('pam_bag.bag_recover:main')
