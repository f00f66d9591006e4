/* The look-up of the scoped and per-receiver dispatchers (composition.py), in C.
 *
 * A layered function's stable function stays a plain Python function (users hold it; on
 * the direct path it takes the head's code). While scopes are alive, or its class has
 * layers of its own, its code is a trampoline, `return FIND[receiver](<arguments>)`, or
 * the body of the head it expects behind `if FIND[receiver] is not None: return
 * FIND(receiver)(<arguments>)`; FIND, a `Finder` of this module, finds the head to run: the same look-up as the
 * pure-Python dispatchers (the caller's scope from the context variable, the receiver's
 * table by id, then by class, each table's cached head, else the Python method composing
 * it), without the bytecode. The trampoline then calls the head from Python (no C frame
 * between them), so a call costs the trampoline's frame, one C call and the chain.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <structmember.h>

typedef struct {
    PyObject_HEAD
    PyObject *function;  /* the LayeredFunction: key of the heads tables */
    PyObject *scope;     /* the runtime's ContextVar of the caller's _Scope */
    PyObject *runtime;   /* the Runtime: `_live_scopes`, `back_to_direct` */
    PyObject *head;      /* the head under the decisive configuration */
    PyObject *objects;   /* receivers by id(object), or None: no receiver look-up */
    PyObject *classes;   /* receivers by class (a dict whose __missing__ composes) */
    PyObject *expected;  /* the head whose code the dispatcher runs itself, or NULL */
    int by_class;        /* the receiver is the class itself (classmethods) */
    vectorcallfunc vectorcall;
    /* The last heads table read and its head for `function` (a table's head for a
     * function is composed once and kept: the table is replaced, never changed, when the
     * configuration or the partials change). */
    PyObject *cached_heads;
    PyObject *cached_head;
#if PY_VERSION_HEX < 0x030C0000
    /* The last receiver found by id, while the table has not changed (its version). */
    void *cached_receiver;
    uint64_t cached_version;
    PyObject *cached_found;
#endif
} Finder;

static PyObject *str_heads, *str_head, *str_live_scopes, *str_back_to_direct;

/* `holder.heads` (a new reference). The holders (_Scope, _Receiver) keep it in a
 * __slots__ slot: read at the slot's offset, found once per type from its member
 * descriptor (the attribute look-up was most of a call's look-up). */
static struct {
    PyTypeObject *type;
    Py_ssize_t offset;
} heads_slots[2];

static PyObject *
heads_of(PyObject *holder)
{
    PyTypeObject *type = Py_TYPE(holder);
    for (size_t i = 0; i < sizeof heads_slots / sizeof heads_slots[0]; i++) {
        if (heads_slots[i].type == type) {
            PyObject *heads = *(PyObject **)((char *)holder + heads_slots[i].offset);
            if (heads != NULL) {
                return Py_NewRef(heads);
            }
            break;
        }
        if (heads_slots[i].type == NULL) {
            PyObject *descriptor = _PyType_Lookup(type, str_heads); /* borrowed */
            if (descriptor != NULL && Py_IS_TYPE(descriptor, &PyMemberDescr_Type)) {
                PyMemberDef *member = ((PyMemberDescrObject *)descriptor)->d_member;
                if (member->type == T_OBJECT_EX && !(member->flags & READONLY)) {
                    Py_INCREF(type); /* kept for the process's life */
                    heads_slots[i].type = type;
                    heads_slots[i].offset = member->offset;
                }
            }
            break;
        }
    }
    return PyObject_GetAttr(holder, str_heads);
}

/* The cached head of `holder.heads` (a plain dict), else `holder.head(function, ...)`. */
static PyObject *
head_of(Finder *self, PyObject *holder, PyObject *scope_argument)
{
    PyObject *function = self->function;
    PyObject *heads = heads_of(holder);
    if (heads == NULL) {
        return NULL;
    }
    if (heads == self->cached_heads) {
        Py_DECREF(heads);
        return Py_NewRef(self->cached_head);
    }
    PyObject *head = PyDict_CheckExact(heads) ? PyDict_GetItemWithError(heads, function) : NULL;
    if (head != NULL) {
        /* The result's reference first: releasing the old cache may run any code. */
        Py_INCREF(head);
        PyObject *old_heads = self->cached_heads, *old_head = self->cached_head;
        self->cached_heads = heads; /* our reference */
        self->cached_head = Py_NewRef(head);
        Py_XDECREF(old_heads);
        Py_XDECREF(old_head);
        return head;
    }
    Py_DECREF(heads);
    if (PyErr_Occurred()) {
        return NULL;
    }
    if (scope_argument == NULL) {
        return PyObject_CallMethodOneArg(holder, str_head, function);
    }
    return PyObject_CallMethodObjArgs(holder, str_head, function, scope_argument, NULL);
}

/* The caller's scope (a new reference, None when there is none). */
static PyObject *
current_scope(Finder *self)
{
    PyObject *scope = NULL;
    if (PyContextVar_Get(self->scope, Py_None, &scope) < 0) {
        return NULL;
    }
    return scope;
}

/* No receiver, or one without layers of its own: the scope's head, else the decisive one.
 * A call with no scope in a process with none alive puts the direct path back. */
static PyObject *
scoped_head(Finder *self, PyObject *scope, int restore_direct)
{
    if (scope != Py_None) {
        return head_of(self, scope, NULL);
    }
    if (restore_direct) {
        PyObject *live = PyObject_GetAttr(self->runtime, str_live_scopes);
        if (live == NULL) {
            return NULL;
        }
        int alive = PyObject_IsTrue(live);
        Py_DECREF(live);
        if (alive < 0) {
            return NULL;
        }
        /* The head this call runs is the one installed when it started. */
        PyObject *head = Py_NewRef(self->head);
        if (!alive) {
            PyObject *done = PyObject_CallMethodOneArg(self->runtime, str_back_to_direct,
                                                       self->function);
            if (done == NULL) {
                Py_DECREF(head);
                return NULL;
            }
            Py_DECREF(done);
        }
        return head;
    }
    return Py_NewRef(self->head);
}

/* The receiver's table: by id (objects with layers of their own), else by class. */
static PyObject *
receiver_of(Finder *self, PyObject *receiver)
{
#if PY_VERSION_HEX < 0x030C0000
    uint64_t version = ((PyDictObject *)self->objects)->ma_version_tag;
    if (receiver == self->cached_receiver && version == self->cached_version) {
        return Py_NewRef(self->cached_found);
    }
#endif
    PyObject *key = PyLong_FromVoidPtr(receiver);
    if (key == NULL) {
        return NULL;
    }
    PyObject *own = PyDict_GetItemWithError(self->objects, key);
    Py_DECREF(key);
    if (own != NULL) {
#if PY_VERSION_HEX < 0x030C0000
        /* The id stays this object's while it is in the table: a collected object
         * leaves it first (a new version). */
        Py_INCREF(own); /* the result's, before releasing the old cache */
        PyObject *old = self->cached_found;
        self->cached_receiver = receiver;
        self->cached_version = version;
        self->cached_found = Py_NewRef(own);
        Py_XDECREF(old);
        return own;
#else
        return Py_NewRef(own);
#endif
    }
    if (PyErr_Occurred()) {
        return NULL;
    }
    PyObject *cls = self->by_class ? receiver : (PyObject *)Py_TYPE(receiver);
    PyObject *found = PyDict_GetItemWithError(self->classes, cls);
    if (found != NULL) {
        return Py_NewRef(found);
    }
    if (PyErr_Occurred()) {
        return NULL;
    }
    return PyObject_GetItem(self->classes, cls); /* __missing__ computes it */
}

/* The head for a call on `receiver` (NULL: none; ignored on the scoped path). */
static PyObject *
find(Finder *self, PyObject *receiver_object)
{
    if (self->function == NULL) { /* Finder.__new__ without __init__, or cleared */
        PyErr_SetString(PyExc_TypeError, "the contextros Finder is not initialised");
        return NULL;
    }
    PyObject *scope = current_scope(self);
    if (scope == NULL) {
        return NULL;
    }
    PyObject *head;
    if (self->objects == Py_None) { /* the scoped path */
        head = scoped_head(self, scope, 1);
        Py_DECREF(scope);
        return head;
    }
    PyObject *receiver =
        receiver_object ? receiver_of(self, receiver_object) : Py_NewRef(Py_None);
    if (receiver == NULL) {
        Py_DECREF(scope);
        return NULL;
    }
    if (receiver == Py_None) {
        head = scoped_head(self, scope, 0);
    }
    else if (scope == Py_None) {
        head = head_of(self, receiver, Py_None);
    }
    else {
        head = PyObject_CallMethodObjArgs(receiver, str_head, self->function, scope, NULL);
    }
    Py_DECREF(receiver);
    Py_DECREF(scope);
    return head;
}

/* FIND(): no receiver; FIND(receiver). */
static PyObject *
finder_vectorcall(PyObject *callable, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    if (kwnames != NULL && PyTuple_GET_SIZE(kwnames)) {
        PyErr_SetString(PyExc_TypeError, "a contextros finder takes no keyword arguments");
        return NULL;
    }
    if (nargs > 1) {
        PyErr_SetString(PyExc_TypeError, "a contextros finder takes at most one argument");
        return NULL;
    }
    return find((Finder *)callable, nargs ? args[0] : NULL);
}

/* FIND[receiver]: the same as FIND(receiver), except that the head the dispatcher expects
 * (whose code it runs itself) is None; and cheaper for the interpreter (a subscript goes
 * straight to this function; a call of a C object does not). */
static PyObject *
finder_subscript(PyObject *self, PyObject *receiver)
{
    PyObject *head = find((Finder *)self, receiver);
    if (head != NULL && head == ((Finder *)self)->expected) {
        Py_DECREF(head);
        Py_RETURN_NONE;
    }
    return head;
}

static PyMappingMethods finder_mapping = {
    .mp_subscript = finder_subscript,
};

static int
finder_traverse(Finder *self, visitproc visit, void *arg)
{
    Py_VISIT(self->function);
    Py_VISIT(self->scope);
    Py_VISIT(self->runtime);
    Py_VISIT(self->head);
    Py_VISIT(self->objects);
    Py_VISIT(self->classes);
    Py_VISIT(self->expected);
    Py_VISIT(self->cached_heads);
    Py_VISIT(self->cached_head);
#if PY_VERSION_HEX < 0x030C0000
    Py_VISIT(self->cached_found);
#endif
    return 0;
}

static int
finder_clear(Finder *self)
{
    Py_CLEAR(self->function);
    Py_CLEAR(self->scope);
    Py_CLEAR(self->runtime);
    Py_CLEAR(self->head);
    Py_CLEAR(self->objects);
    Py_CLEAR(self->classes);
    Py_CLEAR(self->expected);
    Py_CLEAR(self->cached_heads);
    Py_CLEAR(self->cached_head);
#if PY_VERSION_HEX < 0x030C0000
    Py_CLEAR(self->cached_found);
    self->cached_receiver = NULL;
#endif
    return 0;
}

static void
finder_dealloc(Finder *self)
{
    PyObject_GC_UnTrack(self);
    finder_clear(self);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int
finder_init(Finder *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"function", "scope", "runtime", "head", "objects", "classes",
                            "by_class", "expected", NULL};
    PyObject *function, *scope, *runtime, *head, *objects = Py_None, *classes = Py_None;
    PyObject *expected = NULL;
    int by_class = 0;
    /* Its fields stay as set while it lives: a call reads them borrowed, and re-running
     * __init__ from code a call runs would release them under it. */
    if (self->function != NULL) {
        PyErr_SetString(PyExc_TypeError, "the contextros Finder is already initialised");
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOO|OOpO:Finder", names, &function,
                                     &scope, &runtime, &head, &objects, &classes, &by_class,
                                     &expected)) {
        return -1;
    }
    if (!PyContextVar_CheckExact(scope)) {
        PyErr_SetString(PyExc_TypeError, "Finder: scope must be a contextvars.ContextVar");
        return -1;
    }
    if (objects != Py_None && (!PyDict_Check(objects) || !PyDict_Check(classes))) {
        PyErr_SetString(PyExc_TypeError, "Finder: objects and classes must be dicts");
        return -1;
    }
    self->scope = Py_NewRef(scope);
    self->runtime = Py_NewRef(runtime);
    self->head = Py_NewRef(head);
    self->objects = Py_NewRef(objects);
    self->classes = Py_NewRef(classes);
    self->expected = expected == Py_None ? NULL : Py_XNewRef(expected);
    self->by_class = by_class;
    self->function = Py_NewRef(function); /* last: the finder is ready */
    return 0;
}

/* Callable from its creation: a call before __init__ is a TypeError (find), not a crash. */
static PyObject *
finder_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    Finder *self = (Finder *)PyType_GenericNew(type, args, kwargs);
    if (self != NULL) {
        self->vectorcall = finder_vectorcall;
    }
    return (PyObject *)self;
}

static PyMemberDef finder_members[] = {
    {"head", T_OBJECT_EX, offsetof(Finder, head), READONLY,
     "the head under the decisive configuration"},
    {"function", T_OBJECT_EX, offsetof(Finder, function), READONLY, "the layered function"},
    {"objects", T_OBJECT_EX, offsetof(Finder, objects), READONLY,
     "the receivers by id(object) (None: the scoped path)"},
    {"expected", T_OBJECT, offsetof(Finder, expected), READONLY,
     "the head FIND[receiver] gives as None (the dispatcher whose code is that head's "
     "reads this finder, under a global name of its own)"},
    {NULL},
};

static PyTypeObject FinderType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "contextros.core._dispatch.Finder",
    .tp_doc = PyDoc_STR("Finder(function, scope, runtime, head, objects=None, classes=None, "
                        "by_class=False, expected=None): called as FIND[receiver], FIND(receiver) or FIND(), returns the "
                        "head a layered call runs"),
    .tp_basicsize = sizeof(Finder),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_new = finder_new,
    .tp_init = (initproc)finder_init,
    .tp_dealloc = (destructor)finder_dealloc,
    .tp_traverse = (traverseproc)finder_traverse,
    .tp_clear = (inquiry)finder_clear,
    .tp_call = PyVectorcall_Call,
    .tp_vectorcall_offset = offsetof(Finder, vectorcall),
    .tp_members = finder_members,
    .tp_as_mapping = &finder_mapping,
};

static struct PyModuleDef dispatch_module = {
    PyModuleDef_HEAD_INIT,
    .m_name = "contextros.core._dispatch",
    .m_doc = PyDoc_STR("The scoped and per-receiver look-up of layered calls, in C."),
    .m_size = -1,
};

PyMODINIT_FUNC
PyInit__dispatch(void)
{
    str_heads = PyUnicode_InternFromString("heads");
    str_head = PyUnicode_InternFromString("head");
    str_live_scopes = PyUnicode_InternFromString("_live_scopes");
    str_back_to_direct = PyUnicode_InternFromString("back_to_direct");
    if (!str_heads || !str_head || !str_live_scopes || !str_back_to_direct) {
        return NULL;
    }
    if (PyType_Ready(&FinderType) < 0) {
        return NULL;
    }
    PyObject *module = PyModule_Create(&dispatch_module);
    if (module == NULL) {
        return NULL;
    }
    /* What composition.py expects (it falls back to pure Python on a stale build). */
    if (PyModule_AddIntConstant(module, "ABI", 2) < 0 ||
        PyModule_AddObjectRef(module, "Finder", (PyObject *)&FinderType) < 0) {
        Py_DECREF(module);
        return NULL;
    }
    return module;
}
