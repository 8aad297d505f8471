"""Declare ROS parameters from tables, the same way in every followbot node."""

import dataclasses

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """A parameter's default, meaning and, for a number, its accepted range."""

    default: object
    description: str
    low: float | None = None
    high: float | None = None
    read_only: bool = False
    # A parameter that takes values of several types (a count or a list of names, say).
    dynamic_typing: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """
        Build the ROS descriptor, with an integer or floating-point range for numbers.

        :return: the descriptor.
        """
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only,
                                         dynamic_typing=self.dynamic_typing)
        if self.low is None:
            return descriptor
        if isinstance(self.default, int) and not isinstance(self.default, bool):
            descriptor.integer_range = [
                IntegerRange(from_value=int(self.low), to_value=int(self.high))]
        else:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(self.low), to_value=float(self.high))]
        return descriptor


def specs_for_config(config, meanings: dict) -> dict:
    """
    Make parameter specs for every field of a config dataclass, with its defaults.

    :param config: a dataclass instance whose field values are the defaults.
    :param meanings: field name -> description, or (low, high, description) for a number.
    :return: parameter name -> ParameterSpec.
    """
    specs = {}
    for field in dataclasses.fields(config):
        meaning = meanings[field.name]
        default = getattr(config, field.name)
        if isinstance(meaning, str):
            specs[field.name] = ParameterSpec(default, meaning)
        else:
            low, high, description = meaning
            specs[field.name] = ParameterSpec(default, description, low, high)
    return specs


def declare_parameters(node, specs: dict) -> dict:
    """
    Declare parameters on a node and read their values (overrides included).

    :param node: the rclpy node.
    :param specs: parameter name -> ParameterSpec.
    :return: parameter name -> value.
    """
    return {name: node.declare_parameter(name, spec.default, spec.descriptor()).value
            for name, spec in specs.items()}
