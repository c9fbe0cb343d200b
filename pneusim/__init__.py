"""pneusim: physics of servo-pneumatic rigs, solved by SUNDIALS, for benchmarking identification."""

__version__ = "0.1.0"
