# (filled by the rhs port)
