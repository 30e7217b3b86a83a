# (filled by the integrate port)
