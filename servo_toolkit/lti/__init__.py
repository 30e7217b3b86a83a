"""Linear state-space blocks with named signals, in numpy: the toolkit's own linear algebra
for the loop's analyses (:mod:`.system`), python-control systems made from them on request."""
