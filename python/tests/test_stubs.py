"""The typed stubs (isk/_isk.pyi, isk/__init__.pyi) match the module: the
same names, members and parameter names."""

import ast
import inspect
import pathlib
import re

import isk
import isk._isk as ext

PACKAGE = pathlib.Path(isk.__file__).parent


def public(names):
    return {n for n in names if not n.startswith("_")}


def split_top_level(text):
    """Splits at the commas outside brackets."""
    parts, depth, current = [], 0, ""
    for char in text:
        depth += char in "([{"
        depth -= char in ")]}"
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    if current.strip():
        parts.append(current.strip())
    return parts


def pybind_parameters(function):
    """Parameter names (and '*') from pybind11's signature line."""
    line = function.__doc__.splitlines()[0]
    inside = line[line.index("(") + 1:line.rindex(") ->")]
    names = [re.split(r"[:=]", part)[0].strip()
             for part in split_top_level(inside)]
    return [n for n in names if n != "self"]


def stub_parameters(node):
    args = node.args
    names = [a.arg for a in args.posonlyargs + args.args if a.arg != "self"]
    if args.kwonlyargs:
        names += ["*"] + [a.arg for a in args.kwonlyargs]
    return names


def stub_tree():
    return ast.parse((PACKAGE / "_isk.pyi").read_text())


def test_stub_names_match_the_module():
    tree = stub_tree()
    stub = {node.name: node for node in tree.body
            if isinstance(node, (ast.ClassDef, ast.FunctionDef))}
    assert set(stub) == public(dir(ext))
    for name, node in stub.items():
        item = getattr(ext, name)
        if isinstance(node, ast.FunctionDef):
            assert stub_parameters(node) == pybind_parameters(item), name
            continue
        members = {m.name: m for m in node.body
                   if isinstance(m, ast.FunctionDef)}
        annotations = {m.target.id for m in node.body
                       if isinstance(m, ast.AnnAssign)}
        if issubclass(item, BaseException):
            # The attributes set on every raised isk.Error.
            assert annotations == ({"code", "cl_status"} if item is ext.Error
                                   else set())
            continue
        expected = public(dir(item)) | ({"__init__"} if "__init__" in
                                        members else set())
        assert set(members) == expected, name
        for member_name, member in members.items():
            value = inspect.getattr_static(item, member_name)
            if isinstance(value, property):
                continue
            if isinstance(value, staticmethod):
                value = value.__func__
            assert stub_parameters(member) == pybind_parameters(value), (
                f"{name}.{member_name}")


def test_package_stub_reexports_everything():
    tree = ast.parse((PACKAGE / "__init__.pyi").read_text())
    imported = {alias.asname for node in tree.body
                if isinstance(node, ast.ImportFrom) for alias in node.names}
    assert imported == set(isk.__all__) == public(dir(ext))
    assert (PACKAGE / "py.typed").is_file()
