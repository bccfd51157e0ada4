"""Nodes that face the antagonistic PAM rig: the simulated rig (sim_node) and shared helpers."""
