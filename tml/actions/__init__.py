"""The actions: one module per action (or per family of actions) holding what tml knows of it.

Design
------
Every action of the language's catalogue (:data:`tml.language.actions.CATALOGUE`) has one
:class:`~tml.actions.definition.ActionDef`, written in the module of its family
(:mod:`~tml.actions.takeoff_landing`, :mod:`~tml.actions.moves`,
:mod:`~tml.actions.circles`, :mod:`~tml.actions.areas`, :mod:`~tml.actions.hover`,
:mod:`~tml.actions.payload`, :mod:`~tml.actions.camera`, :mod:`~tml.actions.settings`,
:mod:`~tml.actions.raw`) beside the code of each of its stages. A definition has one typed
field per stage (see :data:`~tml.actions.definition.STAGES`: the GUIDED procedure, the
mission items, their expected time, the motion model, the import reading); the stages read
them from one registry (:mod:`tml.actions.registry`), never from tables or ``if`` chains on
action names of their own. The registry is built once, when it is first imported, and refuses
to load when a catalogue action has no definition or a definition lacks a stage's part: a
stage that truly does not apply holds a :class:`~tml.actions.definition.NotApplicable` with
the reason, and the stage's consumer refuses the action with that reason.

Layers
------
``tml.actions`` sits below the engine, the MAVLink layer and the verifier (which read the
registry) and above :mod:`tml.vehicle`, :mod:`tml.language`, :mod:`tml.geo`,
:mod:`tml.patterns` and :mod:`tml.world`, which it may import (tests/test_layout.py). It
never imports pymavlink. The language keeps what validation needs (the argument specs,
:mod:`tml.language.actions`), so that ``tml validate`` never loads this package. The
simulator (sitl/) is not in it: it stays an independent oracle implementing MAVLink
commands as ArduPilot does.

What the action modules share is in toolkits, one per stage: :mod:`tml.actions.guided` (the
steps a procedure flying with commands yields, and the moves several actions make),
:mod:`tml.actions.items` and :mod:`tml.actions.mav` (mission items as plain numbers, no
pymavlink), :mod:`tml.actions.timing` (how long the items are watched for),
:mod:`tml.actions.motion` (the predicted state and step, and the flight model's interface
for ``tml verify``) and :mod:`tml.actions.reading` (items read back by ``tml import``).

Adding an action
----------------
Write its spec in the catalogue (:mod:`tml.language.actions`), its definition with every
stage's part in a module here (a new module is added to
:data:`tml.actions.registry.MODULES`), its reference in docs/language.md (a test checks it
against the registry), and its tests and an example mission. docs/actions.md says more.
"""
