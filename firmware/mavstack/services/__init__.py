"""Optional services a board composes onto an endpoint, in the order of its SERVICES.

A service module has create(ep) (which calls ep.add) and says which others it works with:
    NEEDS = ("commands",)   it does nothing without these: listed, and before it
    AFTER = ("inputs",)     when listed, before it (it looks them up at start-up)
    USES = ("status",)      looked up while running when there (ep.services.get)
    INSTEAD_OF = ("status",)  it does that one's job: never both
compose() checks NEEDS, AFTER and INSTEAD_OF, and refuses a board that breaks them with one line.
"""
import gc


def compose(ep, names):
    """Attach the services `names` (a board's SERVICES) in order -> None, or the one line
    that says why the board cannot be built (then none is attached)."""
    # All the modules first, then the services: what the modules hold stays for good, and
    # a vehicle rebuilt in place (a reboot) then finds the old services' heap in one piece.
    modules = []
    for i in range(len(names)):
        gc.collect()  # keep the heap unfragmented while each service loads
        modules.append(__import__("mavstack.services." + names[i], None, None, ("create",)))
        why = misplaced(modules[i], names, i)
        if why:
            return why
    for module in modules:
        gc.collect()
        module.create(ep)
    return None


def misplaced(module, names, i):
    """Why names[i] (its module given) cannot be built in this order, or None."""
    name = names[i]
    for need in getattr(module, "NEEDS", ()):
        if need not in names:
            return "service %s needs %s: add it to SERVICES, before %s" % (name, need, name)
        if names.index(need) > i:
            return "service %s needs %s: list it before %s in SERVICES" % (name, need, name)
    for other in getattr(module, "INSTEAD_OF", ()):
        if other in names:
            return "service %s replaces %s: list one of them in SERVICES" % (name, other)
    for peer in getattr(module, "AFTER", ()):
        if peer in names and names.index(peer) > i:
            return "service %s comes after %s: list %s before it in SERVICES" % (name, peer, peer)
    return None
