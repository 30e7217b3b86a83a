"""The cam drive of seed 002: :mod:`.geometry` (the cam and its roller follower, as read
from a scene), :mod:`.drive` (follower load, equivalent inertia, clearance) and
:mod:`.kernels` (the compiled scalar functions the time-stepping loops call)."""
