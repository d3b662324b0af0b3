"""The checks `rlq train` runs on a composed config before anything is compiled."""

from pathlib import Path

import pytest

from rlq.config.conf_dir import CONF_DIR
from rlq.errors import ConfigError
from rlq.run.checks.validate import check_run_config
from tests.helpers import compose_config, quick_sample

PRESETS = sorted(path.stem for path in (Path(CONF_DIR) / "experiment").glob("*.yaml"))


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("preset", quick_sample(PRESETS, 4))
def test_every_preset_passes_the_checks(preset):
    check_run_config(compose_config(f"experiment={preset}"))


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("+eval.env.foo=1", "eval.env.foo is not an option of env=cartpole"),
        ("+eval.env.name=lunar", "eval.env.name is not an option"),
        ("+eval.env.max_episode_steps=true", "eval.env.max_episode_steps must be an integer"),
        ("+eval.env.max_episode_steps=0", "eval.env.max_episode_steps must be null or an integer >= 1"),
    ],
)
def test_eval_env_options_are_checked_like_the_env_s(override, message):
    with pytest.raises(ConfigError, match=message):
        check_run_config(compose_config(override))
