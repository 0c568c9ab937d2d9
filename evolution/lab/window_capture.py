"""What this process's window shows on an X display, read back from the X server.

MuJoCo's passive viewer draws in its own thread and OpenGL context, which Python cannot reach,
so the viewer's ``--screenshot`` reads the picture from the X server instead (libX11 through
``ctypes``; libX11 is already loaded by GLFW, so nothing new is needed): the window is the
largest viewable one whose ``_NET_WM_PID`` (set by GLFW) is this process's id, and the screen
area it covers is read with ``XGetImage`` on the root window. That is what the screen shows
there, as ``xwd -root`` or a desktop screenshot tool would capture it, panels and overlays
included. It works on any X server (Xvfb, Xorg, XWayland). Xlib errors are caught while a
capture runs (Xlib's default handler would end the process).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

_IS_VIEWABLE = 2
_Z_PIXMAP = 2
_ALL_PLANES = ctypes.c_ulong(-1).value
_XA_CARDINAL = 6
_ANY_PROPERTY_TYPE = 0
_SUCCESS = 0
_MAX_TREE_DEPTH = 4


class CaptureError(RuntimeError):
    """The window could not be read (no X display, no window of this process, an X error)."""


class _XImage(ctypes.Structure):
    # The leading fields of Xlib's XImage (the function table that follows is not needed).
    _fields_ = [
        ("width", ctypes.c_int), ("height", ctypes.c_int), ("xoffset", ctypes.c_int),
        ("format", ctypes.c_int), ("data", ctypes.c_void_p), ("byte_order", ctypes.c_int),
        ("bitmap_unit", ctypes.c_int), ("bitmap_bit_order", ctypes.c_int),
        ("bitmap_pad", ctypes.c_int), ("depth", ctypes.c_int),
        ("bytes_per_line", ctypes.c_int), ("bits_per_pixel", ctypes.c_int),
        ("red_mask", ctypes.c_ulong), ("green_mask", ctypes.c_ulong),
        ("blue_mask", ctypes.c_ulong),
    ]  # fmt: skip


class _XWindowAttributes(ctypes.Structure):
    _fields_ = [
        ("x", ctypes.c_int), ("y", ctypes.c_int), ("width", ctypes.c_int),
        ("height", ctypes.c_int), ("border_width", ctypes.c_int), ("depth", ctypes.c_int),
        ("visual", ctypes.c_void_p), ("root", ctypes.c_ulong), ("class_", ctypes.c_int),
        ("bit_gravity", ctypes.c_int), ("win_gravity", ctypes.c_int),
        ("backing_store", ctypes.c_int), ("backing_planes", ctypes.c_ulong),
        ("backing_pixel", ctypes.c_ulong), ("save_under", ctypes.c_int),
        ("colormap", ctypes.c_ulong), ("map_installed", ctypes.c_int),
        ("map_state", ctypes.c_int), ("all_event_masks", ctypes.c_long),
        ("your_event_mask", ctypes.c_long), ("do_not_propagate_mask", ctypes.c_long),
        ("override_redirect", ctypes.c_int), ("screen", ctypes.c_void_p),
    ]  # fmt: skip


_ERROR_HANDLER = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)
_errors: list[int] = []


def _record(display: Any, event: Any) -> int:
    _errors.append(1)
    return 0


#: Kept for the life of the process: Xlib calls it through a C pointer.
_record_error = _ERROR_HANDLER(_record)


def _library() -> Any:
    """libX11 with the signatures used here."""
    name = ctypes.util.find_library("X11")
    if name is None:
        raise CaptureError("libX11 is not installed (Debian: libx11-6)")
    x = ctypes.CDLL(name)
    c_ulong_p = ctypes.POINTER(ctypes.c_ulong)
    x.XOpenDisplay.restype = ctypes.c_void_p
    x.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x.XCloseDisplay.argtypes = [ctypes.c_void_p]
    x.XDefaultRootWindow.restype = ctypes.c_ulong
    x.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
    x.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
    x.XFree.argtypes = [ctypes.c_void_p]
    x.XSetErrorHandler.restype = ctypes.c_void_p
    x.XSetErrorHandler.argtypes = [ctypes.c_void_p]
    x.XInternAtom.restype = ctypes.c_ulong
    x.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    x.XQueryTree.argtypes = [
        ctypes.c_void_p, ctypes.c_ulong, c_ulong_p, c_ulong_p,
        ctypes.POINTER(c_ulong_p), ctypes.POINTER(ctypes.c_uint),
    ]  # fmt: skip
    x.XGetWindowAttributes.argtypes = [
        ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(_XWindowAttributes)
    ]
    x.XGetWindowProperty.argtypes = [
        ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_long, ctypes.c_long,
        ctypes.c_int, ctypes.c_ulong, c_ulong_p, ctypes.POINTER(ctypes.c_int), c_ulong_p,
        c_ulong_p, ctypes.POINTER(ctypes.c_void_p),
    ]  # fmt: skip
    x.XTranslateCoordinates.argtypes = [
        ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_int, ctypes.c_int,
        ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int), c_ulong_p,
    ]  # fmt: skip
    x.XGetImage.restype = ctypes.POINTER(_XImage)
    x.XGetImage.argtypes = [
        ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_int, ctypes.c_uint,
        ctypes.c_uint, ctypes.c_ulong, ctypes.c_int,
    ]  # fmt: skip
    x.XDestroyImage.argtypes = [ctypes.POINTER(_XImage)]
    return x


def display_problem() -> str | None:
    """Why no window can be opened here (one line), or None if the X display answers."""
    name = os.environ.get("DISPLAY", "")
    if not name:
        return "no X display (DISPLAY is unset)"
    try:
        x = _library()
    except CaptureError as err:
        return str(err)
    display = x.XOpenDisplay(name.encode())
    if not display:
        return f"cannot open the X display {name!r} (DISPLAY)"
    x.XCloseDisplay(display)
    return None


@contextmanager
def _connection() -> Iterator[tuple[Any, int]]:
    """An own connection to the X server, with X errors recorded instead of fatal."""
    x = _library()
    display = x.XOpenDisplay(None)
    if not display:
        raise CaptureError(f"cannot open the X display {os.environ.get('DISPLAY', '')!r}")
    _errors.clear()
    previous = x.XSetErrorHandler(ctypes.cast(_record_error, ctypes.c_void_p))
    try:
        yield x, display
    finally:
        x.XSync(display, 0)
        x.XSetErrorHandler(previous)
        x.XCloseDisplay(display)


def _children(x: Any, display: int, window: int) -> list[int]:
    root, parent = ctypes.c_ulong(), ctypes.c_ulong()
    children = ctypes.POINTER(ctypes.c_ulong)()
    count = ctypes.c_uint()
    if not x.XQueryTree(
        display, window, ctypes.byref(root), ctypes.byref(parent), ctypes.byref(children),
        ctypes.byref(count),
    ):  # fmt: skip
        return []
    found = [int(children[i]) for i in range(count.value)]
    if children:
        x.XFree(children)
    return found


def _window_pid(x: Any, display: int, window: int, atom: int) -> int | None:
    kind, fmt = ctypes.c_ulong(), ctypes.c_int()
    items, after = ctypes.c_ulong(), ctypes.c_ulong()
    data = ctypes.c_void_p()
    status = x.XGetWindowProperty(
        display, window, atom, 0, 1, 0, _XA_CARDINAL, ctypes.byref(kind), ctypes.byref(fmt),
        ctypes.byref(items), ctypes.byref(after), ctypes.byref(data),
    )  # fmt: skip
    try:
        if status != _SUCCESS or not data.value or items.value < 1 or fmt.value != 32:
            return None
        # Format-32 properties arrive as C longs.
        return int(ctypes.cast(data, ctypes.POINTER(ctypes.c_long))[0])
    finally:
        if data.value:
            x.XFree(data)


def _own_window(x: Any, display: int, pid: int) -> tuple[int, _XWindowAttributes]:
    """The largest viewable window of process ``pid``, searched down the window tree (a window
    manager puts a frame between the root and the application's window)."""
    atom = x.XInternAtom(display, b"_NET_WM_PID", 1)
    if not atom:
        raise CaptureError("no window of this process on the X display (no _NET_WM_PID)")
    best: tuple[int, _XWindowAttributes] | None = None
    level = _children(x, display, x.XDefaultRootWindow(display))
    for _ in range(_MAX_TREE_DEPTH):
        below: list[int] = []
        for window in level:
            attributes = _XWindowAttributes()
            if not x.XGetWindowAttributes(display, window, ctypes.byref(attributes)):
                continue
            if attributes.map_state != _IS_VIEWABLE:
                continue
            if _window_pid(x, display, window, atom) == pid:
                area = attributes.width * attributes.height
                if best is None or area > best[1].width * best[1].height:
                    best = (window, attributes)
            below += _children(x, display, window)
        level = below
    if best is None:
        raise CaptureError("no viewable window of this process on the X display")
    return best


def _to_rgb(image: _XImage) -> np.ndarray:
    """An XImage in ZPixmap format (24 or 32 bits per pixel) as (h, w, 3) uint8 RGB."""
    bpp = image.bits_per_pixel
    if image.format != _Z_PIXMAP or bpp not in (24, 32):
        raise CaptureError(f"unsupported X image format ({bpp} bits per pixel)")
    raw = ctypes.string_at(image.data, image.bytes_per_line * image.height)
    rows = np.frombuffer(raw, np.uint8).reshape(image.height, image.bytes_per_line)
    step = bpp // 8
    bytes_ = rows[:, : image.width * step].reshape(image.height, image.width, step)
    if image.byte_order:  # MSBFirst: most significant byte first
        bytes_ = bytes_[..., ::-1]
    pixels = np.zeros((image.height, image.width), dtype=np.uint32)
    for k in range(step):
        pixels |= bytes_[..., k].astype(np.uint32) << np.uint32(8 * k)
    channels = []
    for mask in (image.red_mask, image.green_mask, image.blue_mask):
        shift = (mask & -mask).bit_length() - 1
        top = mask >> shift
        channel = (pixels >> np.uint32(shift)) & np.uint32(top)
        channels.append((channel * 255 // max(top, 1)).astype(np.uint8))
    return np.stack(channels, axis=-1)


def capture_own_window(pid: int | None = None) -> np.ndarray:
    """What the largest window of this process (or of ``pid``) shows, as (h, w, 3) uint8 RGB.

    The part of the window outside the screen, if any, is left out.

    Raises:
        CaptureError: no X display, no viewable window of the process, or an X error.
    """
    pid = os.getpid() if pid is None else pid
    with _connection() as (x, display):
        window, attributes = _own_window(x, display, pid)
        root = x.XDefaultRootWindow(display)
        left, top, child = ctypes.c_int(), ctypes.c_int(), ctypes.c_ulong()
        if not x.XTranslateCoordinates(
            display, window, root, 0, 0, ctypes.byref(left), ctypes.byref(top),
            ctypes.byref(child),
        ):  # fmt: skip
            raise CaptureError("the window is not on the screen")
        screen = _XWindowAttributes()
        x.XGetWindowAttributes(display, root, ctypes.byref(screen))
        x0, y0 = max(left.value, 0), max(top.value, 0)
        x1 = min(left.value + attributes.width, screen.width)
        y1 = min(top.value + attributes.height, screen.height)
        if x1 <= x0 or y1 <= y0:
            raise CaptureError("the window is not on the screen")
        image = x.XGetImage(display, root, x0, y0, x1 - x0, y1 - y0, _ALL_PLANES, _Z_PIXMAP)
        x.XSync(display, 0)
        if not image or _errors:
            raise CaptureError("the X server refused to read the window (XGetImage failed)")
        try:
            return _to_rgb(image.contents)
        finally:
            x.XDestroyImage(image)
