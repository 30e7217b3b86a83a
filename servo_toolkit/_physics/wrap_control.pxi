# (filled by the control port)
