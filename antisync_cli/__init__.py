"""antisync: antifragility of Kuramoto synchronization to the damage of one link.

A notebook user can compute without touching a file::

    from antisync_cli import graphs
    g = graphs.lollipop(6, 3)

See the README for the command line (``antisync run configs/lollipop6.yaml``).
"""

__version__ = "0.1.0"
