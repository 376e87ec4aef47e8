"""Control: the QP tracking controller, its tasks and limits, references and plant.

- ``controller/``: the QP (paper Eq. 7-8 with a posture task), the step, its certificate.
- ``tasks/``, ``limits/``: what the QP tracks and what bounds it.
- ``layout``: the packed argument vectors (also generated into C); ``plant``: the kinematic plant.
- ``reference``, ``posture``, ``approach``: the references a run follows (base path, arm CoM,
  collision-checked postures, the start-up approach).
"""
