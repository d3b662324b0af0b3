"""What each controller declares of its keys (a frozen dataclass per controller: type, default, allowed values and
meaning), the one home of a ``controller.`` key: the controllers read them (rlq.controllers), rlq/config registers
each in Hydra's ConfigStore as the schema of ``controller=<name>`` (rlq/config/store.py), and
conf/controller/<name>.yaml names that schema. No JAX here."""

from rlq.declared.controllers import cpg, direct

#: each controller's declaration by its name (``controller=<name>``), as rlq.controllers.CONTROLLERS names them
CONTROLLER_CONFIGS: dict[str, type] = {"direct": direct.Config, "cpg": cpg.Config}
