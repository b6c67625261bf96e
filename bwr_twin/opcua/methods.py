"""Method calls answered as OPC UA Part 4 says (the Call service, 5.11.2), which asyncua leaves to
each method: a method called on an object it is not a component of is refused with
BadMethodInvalid, too few arguments with BadArgumentsMissing, too many with
BadTooManyArguments, and arguments of the wrong type with BadInvalidArgument, each argument's
own code (Good or BadTypeMismatch) in the result's InputArgumentResults. Nothing of a refused
call is done. A method may refuse an argument's value the same way (`refuse_argument`).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Sequence

from asyncua import ua

Handler = Callable[..., Awaitable[object]]


def status(code: int) -> ua.StatusCode:
    return ua.StatusCode(code)


def refuse_argument(codes: Sequence[int]) -> ua.CallMethodResult:
    """A call refused for its arguments' values: BadInvalidArgument, each argument's own code."""
    return ua.CallMethodResult(StatusCode=status(ua.StatusCodes.BadInvalidArgument),
                               InputArgumentResults=[status(code) for code in codes])


def checked(handler: Handler, inputs: Sequence[ua.VariantType], owner: ua.NodeId | None) -> Handler:
    """`handler(parent, *arguments)`, called only with the number and types of `inputs` and on
    `owner`, the object the method is a component of (None: any object)."""

    async def call(parent: ua.NodeId, *arguments: ua.Variant):
        if owner is not None and parent != owner:
            return status(ua.StatusCodes.BadMethodInvalid)
        if len(arguments) < len(inputs):
            return status(ua.StatusCodes.BadArgumentsMissing)
        if len(arguments) > len(inputs):
            return status(ua.StatusCodes.BadTooManyArguments)
        codes = [ua.StatusCodes.Good if argument.VariantType == expected else ua.StatusCodes.BadTypeMismatch
                 for argument, expected in zip(arguments, inputs)]
        if any(code != ua.StatusCodes.Good for code in codes):
            return refuse_argument(codes)
        return await handler(parent, *arguments)

    return call
