"""What each algorithm declares of its keys: a frozen dataclass ``Config`` per algorithm whose fields give each key's
type, default, allowed values (``rlq.lib.settings.setting``) and meaning (its comment). The one home of an
``algo.`` key: the algorithm's module reads it (``rlq.algos.ppo.Config`` is ``rlq.declared.ppo.Config``),
rlq/config registers it in Hydra's ConfigStore as the schema of ``algo=<name>`` (rlq/config/store.py), and
conf/algo/<name>.yaml is only that schema's name. Apart from the algorithms so that composing a config imports no
JAX (the algorithms' modules do): these modules import only rlq.lib's declarations."""

from rlq.declared import dqn, es, map_elites, ppo, pqn, qlearning, random_search, reinforce

#: each algorithm's declaration by its name (``algo=<name>``), as rlq.algos.ALGORITHMS names the algorithms
ALGORITHM_CONFIGS: dict[str, type] = {
    "ppo": ppo.Config,
    "dqn": dqn.Config,
    "pqn": pqn.Config,
    "reinforce": reinforce.Config,
    "qlearning": qlearning.Config,
    "random_search": random_search.Config,
    "map_elites": map_elites.Config,
    "es": es.Config,
}
