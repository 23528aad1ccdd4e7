"""`cached_property`: functools.cached_property without the lock Python 3.11 takes."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any, Generic, TypeVar

T = TypeVar("T")

_NOT_FOUND = object()


class _CachedProperty(Generic[T]):
    """A property computed at its first read and kept in the instance's __dict__ (later reads
    find it there and do not call it), as functools.cached_property: its Python 3.12 form,
    which dropped the lock that 3.11's takes at every first read of every instance (~1 us
    each; the validated data of a solve have ~10 such first reads). Works on frozen
    dataclasses (the value goes into __dict__ directly). Two threads reading one property of
    one instance at once may both compute it, as on 3.12: the properties that use it compute
    the same value from immutable data."""

    def __init__(self, func: Callable[[Any], T]) -> None:
        self.func = func
        self.attrname: str | None = None
        self.__doc__ = func.__doc__
        self.__module__ = func.__module__

    def __set_name__(self, owner: type, name: str) -> None:
        if self.attrname is None:
            self.attrname = name
        elif name != self.attrname:
            raise TypeError("Cannot assign the same cached_property to two different names "
                            f"({self.attrname!r} and {name!r}).")

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        if self.attrname is None:
            raise TypeError("Cannot use cached_property instance without calling __set_name__ on it.")
        try:
            cache = instance.__dict__
        except AttributeError:
            raise TypeError(f"No '__dict__' attribute on {type(instance).__name__!r} instance to cache "
                            f"{self.attrname!r} property.") from None
        value = cache.get(self.attrname, _NOT_FOUND)
        if value is _NOT_FOUND:
            value = self.func(instance)
            cache[self.attrname] = value
        return value


#: functools' own from Python 3.12 on (the same, without the lock)
cached_property = functools.cached_property if sys.version_info >= (3, 12) else _CachedProperty
