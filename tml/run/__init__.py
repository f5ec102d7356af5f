"""Flying a mission: the loop that joins the clock, the vehicles and the engine
(:mod:`~tml.run.runner`), the flight log (:mod:`~tml.run.journal`) and the live view
(:mod:`~tml.run.display`)."""
