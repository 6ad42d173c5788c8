"""robovib: pose-dependent dynamics of industrial robots that machine parts."""

__version__ = "0.1.0"
