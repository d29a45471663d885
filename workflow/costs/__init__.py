"""Cost studies: how assembly and reduction scale with the mesh (:mod:`.scaling`), and the
harmonic balance with the contact pairs (:mod:`.interface_scaling`). The ``scaling`` and
``interface_scaling`` stages run them from a scene; ``python -m workflow.bench.<name>`` are
their scripts. Each step runs in a fresh process (``python -m workflow.costs.<name>``) so that
its peak memory is its own."""
