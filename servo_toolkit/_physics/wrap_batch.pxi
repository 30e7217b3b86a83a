# (filled by the batch port)
