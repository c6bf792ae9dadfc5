"""The dock: the live frame, the scene's generation and sources, and the
controls (daemon address, its token and CA file, Follow map, Reload now,
Retry now, pitch and heading). It only shows and asks: the plugin wires it
to the daemon link. While the daemon is away it shows nothing stale: the
frame and the source list are cleared and say so."""

from __future__ import annotations

from typing import Optional

from . import proto_json as pj

from qgis.PyQt.QtCore import QSize, Qt, QTimer, pyqtSignal
from qgis.PyQt.QtGui import QImage, QPixmap
from qgis.PyQt.QtWidgets import (
    QCheckBox,
    QDockWidget,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSizePolicy,
    QSlider,
    QTreeWidget,
    QTreeWidgetItem,
    QVBoxLayout,
    QWidget,
)

#: The frame's shape (width over height): landscape, as a screen is.
ASPECT = 16 / 9

#: How each relief.v1.SourceStatus reads in the list.
STATUS_TEXT = {
    # The enum's 0, which proto3 JSON leaves out ("" here).
    "": "unspecified",
    "SOURCE_STATUS_UNSPECIFIED": "unspecified",
    "SOURCE_STATUS_READY": "ready",
    "SOURCE_STATUS_ERROR": "error (last good version shown)",
    "SOURCE_STATUS_FAILED": "failed (nothing to show)",
}


class _Frame(QLabel):
    """The frame, landscape (ASPECT) and scaled to fit; says when its width
    settles so the stream can be asked for frames of that size. A dock at
    the side of QGIS is tall and narrow: the frames stay landscape in it."""

    resized = pyqtSignal(QSize)

    def __init__(self) -> None:
        super().__init__("waiting for the first frame")
        self.setAlignment(Qt.AlignCenter)
        self.setMinimumSize(160, 90)
        policy = QSizePolicy(QSizePolicy.Expanding, QSizePolicy.Preferred)
        policy.setHeightForWidth(True)
        self.setSizePolicy(policy)
        self._image = QImage()
        self._settle = QTimer(self)
        self._settle.setSingleShot(True)
        self._settle.setInterval(300)
        self._settle.timeout.connect(self._settled)

    def _settled(self) -> None:
        self.resized.emit(self.wanted_size())

    def wanted_size(self) -> QSize:
        """The frame size to ask for: the label's width, landscape."""
        width = max(self.width(), 16)
        return QSize(width, max(16, int(round(width / ASPECT))))

    def hasHeightForWidth(self) -> bool:  # noqa: N802 (Qt's name)
        return True

    def heightForWidth(self, width: int) -> int:  # noqa: N802 (Qt's name)
        return int(round(width / ASPECT))

    def sizeHint(self) -> QSize:  # noqa: N802 (Qt's name)
        return QSize(320, 180)

    def show_image(self, image: QImage) -> None:
        self._image = image
        self._paint()

    def clear_image(self, why: str) -> None:
        """No frame: the old one would show a scene that may be gone."""
        self._image = QImage()
        self.clear()
        self.setText(why)

    def image(self) -> QImage:
        return self._image

    def resizeEvent(self, event) -> None:  # noqa: N802 (Qt's name)
        super().resizeEvent(event)
        self._paint()
        self._settle.start()

    def _paint(self) -> None:
        if not self._image.isNull():
            pixmap = QPixmap.fromImage(self._image)
            self.setPixmap(pixmap.scaled(self.size(), Qt.KeepAspectRatio, Qt.SmoothTransformation))


class ReliefDock(QDockWidget):
    """The relief dock. Signals say what the user asked for."""

    address_changed = pyqtSignal(str)
    #: The bearer token and the CA file, as entered.
    credentials_changed = pyqtSignal(str, str)
    follow_toggled = pyqtSignal(bool)
    reload_clicked = pyqtSignal()
    retry_clicked = pyqtSignal()
    #: Pitch (degrees, negative: below the horizon) and heading, as set.
    pitch_changed = pyqtSignal(float)
    heading_changed = pyqtSignal(float)
    frame_size_changed = pyqtSignal(int, int)
    #: A slider is held (True) or let go (False).
    dragging = pyqtSignal(bool)

    def __init__(
        self,
        address: str,
        parent: Optional[QWidget] = None,
        *,
        token: str = "",
        ca_file: str = "",
        follow: bool = False,
    ) -> None:
        super().__init__("relief 3D view", parent)
        self.setObjectName("ReliefDock")
        #: The generation of the frame shown, and frames shown so far.
        self.frame_generation = 0
        self.frames_shown = 0
        self._quiet = False

        body = QWidget()
        layout = QVBoxLayout(body)

        self.banner = QLabel()
        self.banner.setWordWrap(True)
        self.banner.setStyleSheet("background: #b3261e; color: white; padding: 4px;")
        banner_row = QHBoxLayout()
        banner_row.addWidget(self.banner, 1)
        self.retry_button = QPushButton("Retry now")
        self.retry_button.setToolTip("Connect to reliefd again now, without waiting for the next try")
        self.retry_button.clicked.connect(self.retry_clicked)
        banner_row.addWidget(self.retry_button)
        layout.addLayout(banner_row)
        self.banner.hide()
        self.retry_button.hide()

        self.frame = _Frame()
        self.frame.resized.connect(self._frame_resized)
        layout.addWidget(self.frame, 1)

        self.generation_label = QLabel("not connected")
        layout.addWidget(self.generation_label)
        self.message = QLabel()
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b3261e;")
        self.message.hide()
        layout.addWidget(self.message)

        self.sources = QTreeWidget()
        self.sources.setHeaderLabels(["Source", "Kind", "Status"])
        self.sources.setRootIsDecorated(False)
        self.sources.setMaximumHeight(140)
        layout.addWidget(self.sources)

        form = QFormLayout()
        self.pitch = QSlider(Qt.Horizontal)
        self.pitch.setRange(5, 90)
        self.pitch.setValue(45)
        self.pitch.setToolTip("How far below the horizon the camera looks")
        self.pitch_label = QLabel()
        form.addRow(self.pitch_label, self.pitch)
        self.heading = QSlider(Qt.Horizontal)
        self.heading.setRange(0, 359)
        self.heading.setToolTip("The camera's heading, clockwise from north")
        self.heading_label = QLabel()
        form.addRow(self.heading_label, self.heading)
        self.pitch.valueChanged.connect(self._pitch_moved)
        self.heading.valueChanged.connect(self._heading_moved)
        for slider in (self.pitch, self.heading):
            slider.sliderPressed.connect(self._slider_pressed)
            slider.sliderReleased.connect(self._slider_released)
        self._label_sliders()
        layout.addLayout(form)

        row = QHBoxLayout()
        self.follow = QCheckBox("Follow map")
        self.follow.setToolTip("The map's centre, scale and rotation drive the camera")
        self.follow.setChecked(follow)
        self._follow_toggled(follow, quiet=True)
        self.follow.toggled.connect(self._follow_toggled)
        row.addWidget(self.follow)
        self.reload_button = QPushButton("Reload now")
        self.reload_button.setToolTip("Ask reliefd to read every source's files again now")
        self.reload_button.clicked.connect(self.reload_clicked)
        row.addWidget(self.reload_button)
        layout.addLayout(row)

        connection = QFormLayout()
        self.address = QLineEdit(address)
        self.address.setToolTip(
            "host:port of reliefd (its gRPC port also speaks HTTP), or https://host:port when it serves TLS"
        )
        self.address.editingFinished.connect(self._address_edited)
        connection.addRow("reliefd", self.address)
        self.address_note = QLabel()
        self.address_note.setWordWrap(True)
        connection.addRow("", self.address_note)
        self.token = QLineEdit(token)
        self.token.setEchoMode(QLineEdit.PasswordEchoOnEdit)
        self.token.setPlaceholderText("none")
        self.token.setToolTip(
            "The bearer token a reliefd serving with --token-file wants: a read token shows the scene, "
            "a control token also lets Follow map and the sliders steer its camera and Reload now reload"
        )
        self.token.editingFinished.connect(self._credentials_edited)
        connection.addRow("Token", self.token)
        self.ca_file = QLineEdit(ca_file)
        self.ca_file.setPlaceholderText("the system's CAs")
        self.ca_file.setToolTip(
            "For https://: a PEM file with the CA certificate that signed reliefd's certificate "
            "(trusted besides the system's)"
        )
        self.ca_file.editingFinished.connect(self._credentials_edited)
        connection.addRow("CA file", self.ca_file)
        layout.addLayout(connection)
        self.address_note.hide()

        self.setWidget(body)

    # ------------------------------------------------------------ showing

    def show_frame(self, image: QImage, generation: int, camera: Optional[dict]) -> None:
        """A frame and the camera it was drawn from (None: leave the
        sliders alone, a change of theirs is on its way)."""
        self.frame.show_image(image)
        self.frame_generation = generation
        self.frames_shown += 1
        if camera is not None:
            self._show_camera(camera)

    def show_reachable(self, up: bool, message: str) -> None:
        self.banner.setText(message)
        self.banner.setVisible(not up)
        self.retry_button.setVisible(not up)
        if not up:
            # Nothing stale: the last frame and the sources' "ready" are
            # not what the daemon has now.
            self.generation_label.setText("not connected")
            self.frame.clear_image("disconnected: no frame")
            self.sources.clear()
            self.show_message("")
        elif self.frame.image().isNull():
            self.frame.clear_image("connected: waiting for the first frame")

    def show_address_note(self, note: str) -> None:
        """What was assumed of the address typed (a default port), or why it
        cannot be used ("" hides it)."""
        self.address_note.setText(note)
        self.address_note.setVisible(bool(note))

    def show_state(self, state: dict) -> None:
        name = pj.text(state, "name") or "scene"
        text = f"{name}: generation {pj.integer(state, 'generation')}"
        if pj.text(state, "manifestError"):
            text += f"; manifest not taken: {pj.text(state, 'manifestError')}"
        self.generation_label.setText(text)
        self.sources.clear()
        for source in pj.items(state, "sources"):
            status = STATUS_TEXT.get(pj.text(source, "status"), pj.text(source, "status"))
            if not pj.flag(source, "active"):
                status += ", not used"
            item = QTreeWidgetItem([pj.text(source, "id"), pj.text(source, "kind"), status])
            error = pj.text(source, "error")
            if error:
                item.setText(2, f"{status}: {error}")
                item.setToolTip(2, error)
                item.setForeground(2, Qt.red)
            self.sources.addTopLevelItem(item)
        for column in range(3):
            self.sources.resizeColumnToContents(column)

    def show_message(self, message: str) -> None:
        """What the daemon said when it refused a request (empty: none)."""
        self.message.setText(message)
        self.message.setVisible(bool(message))

    def _show_camera(self, camera: dict) -> None:
        """The sliders follow the camera the frame was drawn from, without
        asking for anything. proto3 JSON leaves out zeros: a camera without
        `headingDeg` looks north (0), one without `pitchDeg` at the horizon."""
        self._quiet = True
        try:
            if not self.pitch.isSliderDown():
                self.pitch.setValue(int(round(-pj.number(camera, "pitchDeg"))))
            if not self.heading.isSliderDown():
                self.heading.setValue(int(round(pj.number(camera, "headingDeg"))) % 360)
        finally:
            self._quiet = False
        self._label_sliders()

    # ------------------------------------------------------------ asking

    def pitch_deg(self) -> float:
        return -float(self.pitch.value())

    def _label_sliders(self) -> None:
        self.pitch_label.setText(f"Pitch {self.pitch.value()}° down")
        self.heading_label.setText(f"Heading {self.heading.value()}°")

    def _pitch_moved(self, value: int) -> None:
        self._label_sliders()
        if not self._quiet:
            self.pitch_changed.emit(-float(value))

    def _heading_moved(self, value: int) -> None:
        self._label_sliders()
        if not self._quiet:
            self.heading_changed.emit(float(value))

    def _frame_resized(self, size: QSize) -> None:
        self.frame_size_changed.emit(size.width(), size.height())

    def _address_edited(self) -> None:
        self.address_changed.emit(self.address.text().strip())

    def _slider_pressed(self) -> None:
        self.dragging.emit(True)

    def _slider_released(self) -> None:
        self.dragging.emit(False)

    def _credentials_edited(self) -> None:
        self.credentials_changed.emit(self.token.text().strip(), self.ca_file.text().strip())

    def _follow_toggled(self, on: bool, quiet: bool = False) -> None:
        # Following, the map's rotation sets the heading.
        self.heading.setEnabled(not on)
        self.heading.setToolTip(
            "Follow map sets the heading from the map's rotation"
            if on
            else "The camera's heading, clockwise from north"
        )
        if not quiet:
            self.follow_toggled.emit(on)
