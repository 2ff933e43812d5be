"""Exact distance fields of voxel worlds on OpenCL devices (PoCL on the CPU, GPUs).

Arrays are numpy arrays of shape (Z, Y, X) in C order (x fastest). A world is a label volume:
any bool or integer dtype, 0 = empty, nonzero = solid (values 1..255 are also palette indices;
only ``format='packed32'`` and ``save_vox`` need every value in 0..255). The semantics are
those of ``voxfield generate`` (DESIGN §3): the distance from every voxel to the nearest solid
voxel. Bad input raises ``TypeError`` or ``ValueError``, arrays beyond the host's or the
device's memory ``MemoryError`` with the numbers, device failures ``RuntimeError``. The GIL is
released while a device works, and one OpenCL context per device is kept for the process.

Submodules: :mod:`voxfield.ndimage` (drop-in ``scipy.ndimage`` distance transforms, SciPy's
convention: distance from each nonzero element to the nearest zero) and :mod:`voxfield.dask`
(the same on ``dask.array`` volumes, block by block, exactly).
"""

from voxfield import _core

__version__ = _core.__version__
__all__ = ["Field", "devices", "distance_transform", "load_vox", "save_vox"]


def devices():
    """List every OpenCL device of every platform.

    Returns
    -------
    list of dict
        One dict per device, as ``voxfield devices --json`` lists them: ``index`` (what
        ``device=`` takes), ``name``, ``vendor``, ``platform``, ``type`` ('cpu', 'gpu', ...),
        ``version``, ``driver``, ``compute_units``, ``global_mem_bytes``, ``max_alloc_bytes``,
        ``local_mem_bytes``, ``max_work_group_size``, ``available``, ``compiler_available``,
        ``extensions``. Empty without an OpenCL platform.
    """
    return _core.devices()


def distance_transform(world, metric="manhattan", signed=False, sampling=None,
                       return_indices=False, max_distance=None, format=None,
                       algorithm="exact", device=None):
    """Distance from every voxel to the nearest solid (nonzero) voxel.

    Distances are between voxel centres, 0 on solids; outside the world counts as empty; with
    no solid voxel at all every value is the format's maximum (+inf for floats).

    Parameters
    ----------
    world : array_like, shape (Z, Y, X)
        A label volume of any bool or integer dtype, nonzero = solid. A C-contiguous uint8 or
        bool array is read where it is; other layouts are made contiguous first. A zero-size
        array gives a zero-size result.
    metric : {'manhattan', 'chebyshev', 'euclidean'}
        L1, L-inf or L2: SciPy's ``distance_transform_cdt(world == 0, metric='taxicab' /
        'chessboard')`` and ``distance_transform_edt(world == 0)``.
    signed : bool
        Empty voxels get +distance to the nearest solid, solid voxels -distance to the
        nearest empty voxel, the world surrounded by empty space (needs a signed format).
    sampling : float or sequence of 3 floats, optional
        Voxel spacing in array order (z, y, x) as in SciPy, or one number for every axis;
        positive and finite. A string is refused.
    return_indices : bool
        Also return an int32 array of shape (3, Z, Y, X) holding the (z, y, x) of a nearest
        solid voxel of every voxel (-1 without solids), SciPy's layout; unsigned fields only.
    max_distance : float, optional
        A bounded field, exact up to this distance (positive) and equal to it beyond
        (saturated); exact algorithm only. None: unbounded.
    format : str, optional
        'u8', 'u16', 'u32', 'packed32' (uint8/uint16/uint32; distances rounded down,
        saturated), 'i8', 'i16', 'i32' (signed, toward zero), 'f32', 'f64'. Default: u16 (i16
        when signed) for manhattan and chebyshev with unit sampling, f32 otherwise.
        'packed32' also holds the palette colour, so it needs every value in 0..255.
    algorithm : str
        'exact' or one of the dissertation's (brute, brute-chunked, fim, fim-host, jfa,
        jfa-host, jfa-fim, lod, monolithic; manhattan, unit sampling, unsigned only).
    device : None, 'cpu', 'gpu' or int
        None: ``$VOXFIELD_DEVICE`` (read at each call), else the first GPU, else the first
        CPU; an int is an index from :func:`devices`.

    Returns
    -------
    field : ndarray, shape (Z, Y, X)
        A new array of the format's dtype, written by the device directly.
    indices : ndarray of int32, shape (3, Z, Y, X)
        Only with ``return_indices=True``.

    Raises
    ------
    TypeError, ValueError
        Bad arguments, with a message naming the argument.
    MemoryError
        The arrays would not fit the host or the device (checked before allocating).
    RuntimeError
        The device failed.
    """
    return _core.distance_transform(world, metric, signed, sampling, return_indices,
                                    max_distance, format, algorithm, device)


class Field(_core.Field):
    """A copy of a world and its distance field kept on the device across edits.

    A front end over the library's scene (``pipeline::Scene``, as ``voxfield replay`` and
    ``voxfield simulate`` are): each edit uploads only the changed voxels and recomputes only
    what it can change, exactly; each :meth:`edit` or :meth:`apply_edits` call can be taken
    back with :meth:`undo` (and :meth:`redo`); :meth:`step_sand` runs the falling-sand
    simulation in place on the device. :meth:`distances` always equals
    :func:`distance_transform` of :meth:`world` with the same arguments.

    A Field belongs to the thread that made it: its methods release the GIL while the device
    works, so one Field must not be used from two threads at once (separate Fields on any
    threads are fine; they share the device's context under a lock).

    Parameters
    ----------
    world : array_like, shape (Z, Y, X)
        As for :func:`distance_transform` (labels above 255 become material 1, except with
        ``format='packed32'``, which refuses them naming the voxel).
    metric, device, format, sampling, signed, max_distance
        As for :func:`distance_transform`.
    algorithm : str
        'exact' (global semantics) or a chunk-local one of the dissertation (brute-chunked,
        lod, monolithic in 16^3 chunks; manhattan only).
    """

    def __init__(self, world, metric="manhattan", device=None, algorithm="exact", format=None,
                 *, sampling=None, signed=False, max_distance=None):
        super().__init__(world, metric, device, algorithm, format, sampling=sampling,
                         signed=signed, max_distance=max_distance)

    def edit(self, op, shape, center, radius, material=1):
        """Apply one brush and update the field.

        Parameters
        ----------
        op : {'place', 'erase', 'paint'}
            'place' sets ``material``, 'erase' sets 0 (material ignored), 'paint' recolours
            solid voxels only.
        shape : {'sphere', 'cube'}
            dx^2+dy^2+dz^2 <= radius^2, or max(|dx|,|dy|,|dz|) <= radius.
        center : sequence of 3 ints
            (x, y, z) in WORLD order, i.e. array index [z, y, x]; may lie outside the world,
            which clips the brush.
        radius : int
            Non-negative.
        material : int
            Palette index 1..255.

        Returns
        -------
        dict
            ``edits``, ``voxels_changed``, ``voxels_recomputed``, ``update_ms`` (device time)
            and ``full_regeneration``.
        """
        return super().edit(op, shape, center, radius, material)

    def apply_edits(self, text):
        """Apply the edits of an edit file's text in order, as one batch.

        Parameters
        ----------
        text : str
            ``voxfield replay``'s format: one 'place|erase|paint sphere|cube X Y Z R
            [MATERIAL]' per line, '#' comments. The whole text is checked first: a bad line
            raises ``ValueError('edits:LINE: ...')`` and changes nothing.

        Returns
        -------
        dict
            The batch's stats, as :meth:`edit` returns them.
        """
        return super().apply_edits(text)

    def undo(self):
        """Take back the newest :meth:`edit` or :meth:`apply_edits` call not undone yet.

        The voxels it changed get their values from before it, and the field is updated
        exactly as for an edit. Undo history: the last 256 calls, at most 64 Mi voxel
        changes (16 bytes each on the host); :meth:`step_sand` steps are not in it and are
        never undone.

        Returns
        -------
        dict
            The update's stats, as :meth:`edit` returns them; ``edits`` is 0 when there was
            nothing to undo.

        Raises
        ------
        ValueError
            A sand step since moved a voxel of that call: nothing changes, and the undo and
            redo history is cleared.
        """
        return super().undo()

    def redo(self):
        """Apply again the newest call that :meth:`undo` took back.

        A new :meth:`edit` or :meth:`apply_edits` call clears what can be redone.

        Returns
        -------
        dict
            As :meth:`undo` (``edits`` 0 when there was nothing to redo).

        Raises
        ------
        ValueError
            As :meth:`undo`.
        """
        return super().redo()

    def step_sand(self, steps=1, *, seed=1, sand=2, water=3):
        """Run steps of the falling-sand simulation on the device, updating the field.

        The block automaton of ``voxfield simulate`` (DESIGN §4): sand falls, also diagonally,
        and sinks through water; water falls and spreads sideways; every other material stays.
        Each material's voxel count is kept. The steps run in place on the device's copy of
        the world and hand the field update their changes there; :meth:`world` reads the
        result back. Steps are numbered on from the Field's previous ones, so
        ``step_sand(n, seed=s)`` on a new Field gives the world of ``voxfield simulate
        --steps n --seed s``, and ``step_sand(a)`` then ``step_sand(b)`` equals
        ``step_sand(a + b)``.

        Parameters
        ----------
        steps : int
            How many steps (>= 0).
        seed : int
            The simulation's seed, 0..2**64-1.
        sand, water : int
            The sand and the water materials: different, each 1..255.

        Returns
        -------
        dict
            ``steps``, ``voxels_changed`` and ``voxels_recomputed`` (summed over the steps),
            ``simulate_ms`` and ``update_ms`` (summed device times) and
            ``full_regenerations`` (steps whose update regenerated the whole field).
        """
        return super().step_sand(steps, seed=seed, sand=sand, water=water)

    def distances(self):
        """Return the current field.

        Returns
        -------
        ndarray, shape (Z, Y, X)
            In the field's format, read from the device straight into a new array.
        """
        return super().distances()

    def world(self):
        """Return a copy of the current world.

        Where sand steps changed it on the device, the changed region is read back first.

        Returns
        -------
        ndarray of uint8, shape (Z, Y, X)
        """
        return super().world()


def load_vox(path):
    """Read a MagicaVoxel .vox file (its first model).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    world : ndarray of uint8, shape (Z, Y, X)
        MagicaVoxel's z-up turned into y-up: vox (x, y, z) -> world (x, z, y).
    palette : ndarray of uint8, shape (256, 4)
        RGBA of every voxel value (MagicaVoxel's default when the file has none).

    Raises
    ------
    ValueError
        A missing or malformed file.
    """
    return _core.load_vox(path)


def save_vox(path, world, palette=None):
    """Write a MagicaVoxel .vox (version 150) that :func:`load_vox` reads back unchanged.

    The file is written to a temporary name and renamed, never left partial.

    Parameters
    ----------
    path : str or os.PathLike
    world : array_like, shape (Z, Y, X)
        As for :func:`distance_transform`, every value in 0..255 (a palette index) and every
        axis at most 256 (the format's limit).
    palette : array_like of int, shape (256, 4), optional
        RGBA, 0..255; None: MagicaVoxel's default.
    """
    _core.save_vox(path, world, palette)
