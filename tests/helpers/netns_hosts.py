"""The addresses of the hosts :class:`cekm_swarm.runtime.netns.Hosts` makes for two robots:
the world host's end of each robot's link, and the robot's own."""

ROBOTS = ("r1", "r2")
WORLD_ADDR = {"r1": "10.199.1.1", "r2": "10.199.2.1"}
ROBOT_ADDR = {"r1": "10.199.1.2", "r2": "10.199.2.2"}
