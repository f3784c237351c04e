"""Power grids: static indicators of a line (``grid``) and dynamic N-1 by random starts
(``removal``), both on the generalized model of :mod:`antisync.plan.model`.
"""
