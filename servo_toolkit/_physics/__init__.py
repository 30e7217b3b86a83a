"""The compiled physics kernels (C99, built with the package): :mod:`._kernels`."""
