"""The mission language: the model, reading and building it from XML, the schema, the
semantic checks and their diagnostics, and the vocabulary (actions, parameters, skills,
vehicle kinds).

The pipeline runs :mod:`~tml.language.xml` (hardened reading) -> :mod:`~tml.language.schema`
-> :mod:`~tml.language.build` (the model) -> :mod:`~tml.language.check`;
:mod:`~tml.language.validation` runs it for one file.
"""
