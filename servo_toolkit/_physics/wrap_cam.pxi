# (filled by the cam port)
