"""Every figure of the project (matplotlib, Agg): the campaign report's figures and their
drawing helpers (:mod:`.report`), one run's plot (:mod:`.run`), one aircraft-level run's plot
(:mod:`.aircraft`) and the report's trade-off figure (:mod:`.tradeoff`)."""
