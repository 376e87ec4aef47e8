"""On the robot (``docs/online.md``): elevation maps and odometry in, arm command and μ out.

- ``stream``: a recording's maps paired with the odometry received by then;
- ``horizon``: the receding horizon of planned poses ahead of the robot, re-planned when the
  map changes their ground;
- ``follow``: the loop, one update per map (rest, re-plan, controller step), and its run.
"""
