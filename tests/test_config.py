"""Settings: one-line messages for invalid values."""

import pytest
from pydantic import ValidationError

from bicoord_drake.config import StationConfig, validation_message
from bicoord_drake.runner.generate import GenerateConfig


def _error(model, **values) -> ValidationError:
    with pytest.raises(ValidationError) as info:
        model(**values)
    return info.value


def test_validation_message_names_the_field_in_one_line():
    err = _error(GenerateConfig, task="jigsaw", episodes=0)
    message = validation_message(err)
    assert message.startswith("episodes: ") and "\n" not in message
    assert validation_message(err, as_option=True).startswith("--episodes: ")


def test_validation_message_for_nested_and_validator_errors():
    nested = validation_message(_error(StationConfig, cameras={"width": -1}))
    assert nested.startswith("cameras.width: ")
    option = validation_message(
        _error(GenerateConfig, task="jigsaw", resolution="wide"), as_option=True
    )
    assert option.startswith("--resolution: ") and "Value error, " not in option
