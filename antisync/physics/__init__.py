"""Physics: networks and their couplings, initial phases and locked states (pure functions).

``graphs`` builds networkx graphs with the paper's labels and reads graph files, ``coupling``
turns ``Omega`` into ``W`` (normalized or raw), ``phases`` draws the counter-based initial
phases, ``locked`` finds phase-locked states and their linearization. The lowest stage: it
imports only the ground files at the package root.
"""
