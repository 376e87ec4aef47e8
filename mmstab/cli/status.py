"""Exit statuses of ``mmstab`` (``docs/cli.md``)."""

#: Exit statuses.
EXIT_OK, EXIT_BAD_INPUT, EXIT_UNSTABLE, EXIT_INTERRUPTED = 0, 2, 3, 130
#: The tracks would slide (``--allow-sliding`` accepts it).
EXIT_SLIDES = 4
#: A tracked run whose arm touched the robot or came closer than the required clearance.
EXIT_ARM_COLLISION = 5
#: The planner gave up or no plan exists (``PlanningError``): not bad input.
EXIT_NO_PLAN = 6
#: Its stdout's reader left (``mmstab rest ... | head``): 128 + SIGPIPE, as a C program's.
EXIT_BROKEN_PIPE = 141
